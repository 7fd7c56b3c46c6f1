//! `cargo xtask stage NAME --in A --in B --out C`: one stage alone, for outside schedulers.

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::time::Instant;

use anyhow::{Context as _, Result, bail};
use mocap_io::artifact::{self, ArtifactHeader, InputHash};

use crate::pipeline::{self, CAPTURE_ROLE, Params, Products, StageId};
use crate::set_param;

/// Arguments of `stage`.
#[derive(clap::Args)]
#[command(after_help = "\
Inputs are recognised by their artifact header, so their order does not matter:
  mocap-io  --in CAPTURE (.c3d/.trc/.csv/.tsv)
  segment   --in mocap-io.cbor
  jointfit  --in mocap-io.cbor --in segment.cbor
  topo      --in segment.cbor --in jointfit.cbor
  bonefit   --in mocap-io.cbor --in segment.cbor --in jointfit.cbor --in topo.cbor
  export    --in mocap-io.cbor --in segment.cbor --in jointfit.cbor --in topo.cbor --in bonefit.cbor
For export, --out ending in .cbor writes the Outputs artifact (file name → bytes); any \
other --out is a folder that receives skeleton.json, skeleton.bvh, skeleton.glb, joints.csv, \
joints.trc, joints.c3d, markers.trc, markers.c3d, skeleton.osim, skeleton.mot, report.html.
The artifact written is byte-identical to the one `cargo xtask run` caches for the same \
inputs and parameters.")]
pub struct Args {
    /// Stage to run: mocap-io, segment, jointfit, topo, bonefit or export.
    pub name: String,
    /// An input: the capture file for mocap-io, else an upstream artifact. Repeatable.
    #[arg(long = "in", value_name = "FILE", required = true)]
    pub inputs: Vec<PathBuf>,
    /// Output artifact (.cbor); for export, a .cbor artifact or a folder for the files.
    #[arg(long, value_name = "PATH")]
    pub out: PathBuf,
    /// A settings file (a skeleton.json, or a JSON object of "STAGE.PARAM": value): this
    /// stage's entries apply, and the inputs must have been made with the upstream ones.
    #[arg(long, value_name = "FILE")]
    pub settings: Option<PathBuf>,
    /// Set one of this stage's parameters (STAGE.PARAM=VALUE), after --settings. Repeatable.
    #[arg(long = "set", value_name = "STAGE.PARAM=VALUE")]
    pub set: Vec<String>,
}

/// Runs `stage`.
pub fn main(args: &Args) -> Result<()> {
    let start = Instant::now();
    let written = execute(args)?;
    eprintln!(
        "{} done in {:.3} s: {}",
        args.name,
        start.elapsed().as_secs_f64(),
        written
            .iter()
            .map(|p| p.display().to_string())
            .collect::<Vec<_>>()
            .join(", ")
    );
    Ok(())
}

/// Runs one stage and writes its output; returns the paths written.
pub fn execute(args: &Args) -> Result<Vec<PathBuf>> {
    let stage = StageId::from_name(&args.name)?;
    // The whole file is read (a wrong name anywhere in it fails here); its upstream entries
    // are checked against the inputs below, and its downstream ones are other commands'.
    let from_file = match &args.settings {
        Some(path) => Params::from_assignments(&crate::run::settings_file(path)?)
            .with_context(|| format!("--settings {}", path.display()))?,
        None => Params::default(),
    };
    let mut params = from_file.clone();
    for text in &args.set {
        let a = set_param::parse_assignment(text)?;
        if a.stage != stage.name() {
            bail!(
                "--set {text}: this run is stage {}, not {}",
                stage.name(),
                a.stage
            );
        }
        params.set(&a)?;
    }
    let names = || {
        args.inputs
            .iter()
            .map(|p| p.display().to_string())
            .collect::<Vec<_>>()
            .join(", ")
    };

    let mut products = Products::default();
    let (inputs, capture_file) = if stage == StageId::MocapIo {
        let [file] = args.inputs.as_slice() else {
            bail!("mocap-io takes exactly one --in: the capture file");
        };
        let bytes =
            std::fs::read(file).with_context(|| format!("{}: cannot read", file.display()))?;
        let hash = InputHash {
            role: CAPTURE_ROLE.into(),
            blake3: artifact::content_hash(&bytes),
        };
        (vec![hash], Some(file.as_path()))
    } else {
        let mut hashes = BTreeMap::new();
        let mut headers = BTreeMap::new();
        for path in &args.inputs {
            // Header and hash first, then the payload: each read as the file streams in,
            // never the whole file in memory beside its value.
            let (header, hash) = artifact::read_header_hashed(path)?;
            let from = StageId::from_name(&header.stage)
                .with_context(|| format!("{}: artifact of an unknown stage", path.display()))?;
            if !stage.inputs().contains(&from) {
                bail!(
                    "{}: a {} artifact, but {} reads {}",
                    path.display(),
                    from.name(),
                    stage.name(),
                    stage_list(stage.inputs())
                );
            }
            if hashes.contains_key(&from) {
                bail!("{}: a second {} artifact", path.display(), from.name());
            }
            let (_, payload, read) = pipeline::read_payload(from, path)?;
            if read != hash {
                bail!("{}: changed while it was read", path.display());
            }
            products.put(payload);
            hashes.insert(from, hash);
            headers.insert(from, (path.as_path(), header));
        }
        check_consistent(&headers, &hashes)?;
        // The upstream stages' parameters as their artifacts recorded them: export writes
        // them into skeleton.json's settings, as `run` does.
        for (&from, (path, header)) in &headers {
            params
                .take_recorded(from, &header.params)
                .with_context(|| path.display().to_string())?;
            if let Some(file) = &args.settings {
                check_made_with(&from_file, &params, from, path, file)?;
            }
        }
        let missing: Vec<StageId> = stage
            .inputs()
            .iter()
            .copied()
            .filter(|s| !hashes.contains_key(s))
            .collect();
        if !missing.is_empty() {
            bail!(
                "{} also needs the {} artifact(s): add --in for each",
                stage.name(),
                stage_list(&missing)
            );
        }
        let inputs = stage
            .inputs()
            .iter()
            .map(|s| InputHash {
                role: s.name().into(),
                blake3: hashes.get(s).cloned().unwrap_or_default(),
            })
            .collect();
        (inputs, None)
    };

    let failed = || format!("stage {} failed on {}", stage.name(), names());
    let header = pipeline::header(stage, &params, inputs)?;
    if stage == StageId::Export {
        // Export's files are written one at a time as they are made, into the folder or
        // into the artifact, never all in memory.
        let to_artifact = args
            .out
            .extension()
            .is_some_and(|e| e.eq_ignore_ascii_case("cbor"));
        if !to_artifact {
            let (exported, _) = products
                .export_to(&params, Some(&args.out), None)
                .with_context(failed)?;
            return Ok(exported.files);
        }
        let (_, writer) = products
            .export_to(&params, None, Some((&args.out, &header)))
            .with_context(failed)?;
        let writer = writer.context("export's artifact writer went missing")?;
        writer.finish().1?;
        return Ok(vec![args.out.clone()]);
    }
    let payload = products
        .compute(stage, &params, capture_file)
        .with_context(failed)?;
    payload.write(&args.out, &header)?;
    Ok(vec![args.out.clone()])
}

/// Checks that the inputs belong together: every upstream hash an input's header recorded
/// must be the hash of the artifact passed for that role, when that role was passed too.
///
/// Without this, a capture of one trial and a segmentation of another would run (or fail
/// obscurely) and write an artifact whose header claims inputs it was never made from.
fn check_consistent(
    headers: &BTreeMap<StageId, (&Path, ArtifactHeader)>,
    hashes: &BTreeMap<StageId, String>,
) -> Result<()> {
    for (path, header) in headers.values() {
        for recorded in &header.inputs {
            // Roles that are not stages ("capture") are never passed to `stage` here.
            let Ok(role) = StageId::from_name(&recorded.role) else {
                continue;
            };
            let (Some(actual), Some((other, _))) = (hashes.get(&role), headers.get(&role)) else {
                continue;
            };
            if *actual != recorded.blake3 {
                bail!(
                    "{} was made from a different {} artifact than {}: the inputs do not \
                     belong together (recorded {} blake3 {}, given {})",
                    path.display(),
                    recorded.role,
                    other.display(),
                    recorded.role,
                    recorded.blake3,
                    actual
                );
            }
        }
    }
    Ok(())
}

/// Checks that an input artifact of stage `from` was made with the parameters the settings
/// file gives that stage; otherwise the output would not be what the file describes.
fn check_made_with(
    from_file: &Params,
    recorded: &Params,
    from: StageId,
    artifact: &Path,
    file: &Path,
) -> Result<()> {
    let (wanted, made) = (from_file.json(from)?, recorded.json(from)?);
    let (Some(wanted), Some(made)) = (wanted.as_object(), made.as_object()) else {
        return Ok(());
    };
    let differ: Vec<String> = wanted
        .iter()
        .filter(|(name, value)| made.get(*name) != Some(*value))
        .map(|(name, value)| {
            let was = made.get(name).map_or("absent".into(), |v| v.to_string());
            format!(
                "{}.{name} {value} in the file, {was} in the artifact",
                from.name()
            )
        })
        .collect();
    if !differ.is_empty() {
        bail!(
            "{} was made with other {} settings than --settings {} gives ({}): run stage {} \
             with --settings first",
            artifact.display(),
            from.name(),
            file.display(),
            differ.join("; "),
            from.name()
        );
    }
    Ok(())
}

fn stage_list(stages: &[StageId]) -> String {
    stages
        .iter()
        .map(|s| s.name())
        .collect::<Vec<_>>()
        .join(", ")
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::tempdir::TempDir;

    /// A small synthetic capture (C3D) of one trial, named by its seed.
    fn capture(dir: &Path, seed: u64) -> PathBuf {
        let config = synth::SynthConfig {
            subject: synth::Subject::Snowman,
            frames: 120,
            seed,
            ..synth::SynthConfig::default()
        };
        let trial = synth::generate(&config).unwrap();
        let path = dir.join(format!("trial{seed}.c3d"));
        mocap_io::write_c3d(&path, &trial.trajectories).unwrap();
        path
    }

    fn stage(name: &str, inputs: &[&Path], out: PathBuf) -> Result<PathBuf> {
        execute(&Args {
            name: name.into(),
            inputs: inputs.iter().map(|p| p.to_path_buf()).collect(),
            out: out.clone(),
            settings: None,
            set: Vec::new(),
        })?;
        Ok(out)
    }

    #[test]
    fn inputs_from_different_trials_are_refused() {
        let dir = TempDir::new("stage-mix").unwrap();
        let d = dir.path();
        let (a, b) = (capture(d, 11), capture(d, 12));
        let cap_a = stage("mocap-io", &[&a], d.join("a-mocap-io.cbor")).unwrap();
        let cap_b = stage("mocap-io", &[&b], d.join("b-mocap-io.cbor")).unwrap();
        let seg_b = stage("segment", &[&cap_b], d.join("b-segment.cbor")).unwrap();

        // Same trial: accepted.
        stage("jointfit", &[&cap_b, &seg_b], d.join("b-jointfit.cbor")).unwrap();

        // Capture of trial a, segmentation of trial b: refused, naming both and the role.
        let out = d.join("mixed-jointfit.cbor");
        let err = stage("jointfit", &[&cap_a, &seg_b], out.clone()).unwrap_err();
        let text = format!("{err:#}");
        assert!(text.contains("b-segment.cbor"), "{text}");
        assert!(text.contains("a-mocap-io.cbor"), "{text}");
        assert!(text.contains("different mocap-io artifact"), "{text}");
        assert!(!out.exists());
    }
}
