//! The stage graph: which stage reads which artifacts, how each is computed (in-process,
//! by calling the stage crate), encoded, decoded, keyed and reused from the cache.
//!
//! ```text
//! capture file ─► mocap-io ─► segment ─► jointfit ─► topo ─► bonefit ─► export
//!                    │           │          │          │        ▲  ▲       ▲
//!                    └───────────┴──────────┴──────────┴────────┘  │       │
//!                    (bonefit reads capture, segment, jointfit, topo; export reads all)
//! ```
//!
//! Artifact inputs are identified by role = the upstream stage's name, and hashed by the
//! blake3 of the upstream artifact's bytes; mocap-io's one input is the capture file
//! (role "capture", the blake3 of the file's bytes).

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::time::Instant;

use anyhow::{Context as _, Result, anyhow, bail};
use bonefit::Skeleton;
use jointfit::PairFits;
use mocap_io::artifact::{self, ArtifactHeader, ByteMapReader, ByteMapWriter, FileSet, InputHash};
use mocap_io::{Capture, ReadOptions};
use segment::Segmentation;
use serde::Serialize;
use serde_json::{Value as Json, json};
use topo::Topology;

use crate::cache::{self, Cache};
use crate::progress::Progress;
use crate::set_param::{self, Assignment};

/// Version of ossify written into artifact headers.
pub const TOOL_VERSION: &str = env!("CARGO_PKG_VERSION");

/// Role name of mocap-io's input, the capture file.
pub const CAPTURE_ROLE: &str = "capture";

/// Meanings of mocap-io's parameters ([`ReadOptions`]), which mocap-io documents on the type.
pub const READ_PARAM_DOCS: &[(&str, &str)] = &[
    (
        "keep_invalid_residuals",
        "C3D: keep samples with a negative residual when a file flags every sample invalid \
         although its coordinates vary (SIMI writes such files); default false: read them as \
         missing, with a warning",
    ),
    (
        "keep_model_outputs",
        "C3D: keep the points listed in POINT:ANGLES, FORCES, MOMENTS, POWERS, SCALARS, \
         REACTIONS or a group POINT:TYPE_GROUPS names (angles, forces and the like stored as \
         points), and the points no camera saw (every sample's residual word 0) in a file \
         whose other points cameras did see (bone-model and virtual points); default false: \
         they are not read, with a warning",
    ),
    (
        "units",
        "mm, cm, m or in: the unit of the file's coordinates, over what the file declares \
         (even a unit the reader does not know) or what is guessed where it declares none; \
         a warning says when it differs; default null: the file's word, else millimetres \
         (metres for a C3D whose coordinates are all under 10)",
    ),
    (
        "frames",
        "[first, last]: read only these frames, by the file's own frame numbers (what \
         `cargo xtask inspect` shows), both included; outputs keep those numbers; a range the \
         file does not hold is an error; default null: every frame",
    ),
    (
        "exclude_markers",
        "[\"LABEL\", ...]: markers to leave out, by label as the capture names them (a \
         repeated label's later markers LABEL#2, ...; * stands for any run of characters): a \
         loose marker, a prop or floor marker, virtual points; a label or pattern that \
         matches no marker is an error; default []",
    ),
    (
        "stitch",
        "join tracks that are one marker seen in pieces (an unlabeled capture starts a new \
         track at every occlusion): a piece that ends continues as the piece that starts \
         within 1 s where the rigid motion of its steady neighbours carries it, uniquely; \
         a warning lists what was joined; default true (a capture with nothing to join \
         reads unchanged)",
    ),
];

/// One stage of the pipeline, in pipeline order.
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord, Hash)]
pub enum StageId {
    /// Capture file → [`Capture`].
    MocapIo,
    /// → [`Segmentation`].
    Segment,
    /// → [`PairFits`].
    Jointfit,
    /// → [`Topology`].
    Topo,
    /// → [`Skeleton`].
    Bonefit,
    /// → [`export::Outputs`].
    Export,
}

impl StageId {
    /// Every stage, upstream first.
    pub const ALL: [StageId; 6] = [
        StageId::MocapIo,
        StageId::Segment,
        StageId::Jointfit,
        StageId::Topo,
        StageId::Bonefit,
        StageId::Export,
    ];

    /// The stage's name (its crate's `STAGE`).
    pub fn name(self) -> &'static str {
        match self {
            StageId::MocapIo => mocap_io::STAGE,
            StageId::Segment => segment::STAGE,
            StageId::Jointfit => jointfit::STAGE,
            StageId::Topo => topo::STAGE,
            StageId::Bonefit => bonefit::STAGE,
            StageId::Export => export::STAGE,
        }
    }

    /// The schema version of the stage's artifact.
    pub fn schema_version(self) -> u32 {
        match self {
            StageId::MocapIo => mocap_io::SCHEMA_VERSION,
            StageId::Segment => segment::SCHEMA_VERSION,
            StageId::Jointfit => jointfit::SCHEMA_VERSION,
            StageId::Topo => topo::SCHEMA_VERSION,
            StageId::Bonefit => bonefit::SCHEMA_VERSION,
            StageId::Export => export::SCHEMA_VERSION,
        }
    }

    /// The artifacts the stage reads (mocap-io reads the capture file instead).
    pub fn inputs(self) -> &'static [StageId] {
        use StageId::*;
        match self {
            MocapIo => &[],
            Segment => &[MocapIo],
            Jointfit => &[MocapIo, Segment],
            Topo => &[Segment, Jointfit],
            Bonefit => &[MocapIo, Segment, Jointfit, Topo],
            Export => &[MocapIo, Segment, Jointfit, Topo, Bonefit],
        }
    }

    /// The stage's `PARAM_DOCS`.
    pub fn param_docs(self) -> &'static [(&'static str, &'static str)] {
        match self {
            StageId::MocapIo => READ_PARAM_DOCS,
            StageId::Segment => segment::PARAM_DOCS,
            StageId::Jointfit => jointfit::PARAM_DOCS,
            StageId::Topo => topo::PARAM_DOCS,
            StageId::Bonefit => bonefit::PARAM_DOCS,
            StageId::Export => export::PARAM_DOCS,
        }
    }

    /// The stage of a name; the error lists the valid names.
    pub fn from_name(name: &str) -> Result<StageId> {
        StageId::ALL
            .into_iter()
            .find(|s| s.name() == name)
            .ok_or_else(|| {
                let names: Vec<_> = StageId::ALL.iter().map(|s| s.name()).collect();
                anyhow!("unknown stage '{name}'; stages: {}", names.join(", "))
            })
    }
}

/// Cache bucket names of the current stages (`<stage>-v<schema>`), for pruning.
pub fn buckets() -> Vec<String> {
    StageId::ALL
        .iter()
        .map(|s| Cache::bucket_name(s.name(), s.schema_version()))
        .collect()
}

/// The parameters of every stage.
#[derive(Clone, Debug, Default)]
pub struct Params {
    /// mocap-io: how captures are read.
    pub mocap_io: ReadOptions,
    /// segment stage.
    pub segment: segment::Params,
    /// jointfit stage.
    pub jointfit: jointfit::Params,
    /// topo stage.
    pub topo: topo::Params,
    /// bonefit stage.
    pub bonefit: bonefit::Params,
    /// export stage.
    pub export: export::Params,
}

impl Params {
    /// Defaults with `STAGE.PARAM=VALUE` assignments applied in order.
    pub fn from_assignments(assignments: &[String]) -> Result<Params> {
        let mut params = Params::default();
        for text in assignments {
            params.set(&set_param::parse_assignment(text)?)?;
        }
        Ok(params)
    }

    /// Applies one assignment.
    pub fn set(&mut self, a: &Assignment) -> Result<()> {
        let stage = StageId::from_name(&a.stage).with_context(|| format!("--set {}", a.text))?;
        let docs = stage.param_docs();
        match stage {
            StageId::MocapIo => self.mocap_io = set_param::apply(&self.mocap_io, a, docs)?,
            StageId::Segment => self.segment = set_param::apply(&self.segment, a, docs)?,
            StageId::Jointfit => self.jointfit = set_param::apply(&self.jointfit, a, docs)?,
            StageId::Topo => self.topo = set_param::apply(&self.topo, a, docs)?,
            StageId::Bonefit => self.bonefit = set_param::apply(&self.bonefit, a, docs)?,
            StageId::Export => self.export = set_param::apply(&self.export, a, docs)?,
        }
        Ok(())
    }

    /// A stage's parameters as canonical CBOR (what goes into headers and keys).
    pub fn canonical(&self, stage: StageId) -> Result<ciborium::Value> {
        match stage {
            StageId::MocapIo => cache::canonical_value(&self.mocap_io),
            StageId::Segment => cache::canonical_value(&self.segment),
            StageId::Jointfit => cache::canonical_value(&self.jointfit),
            StageId::Topo => cache::canonical_value(&self.topo),
            StageId::Bonefit => cache::canonical_value(&self.bonefit),
            StageId::Export => cache::canonical_value(&self.export),
        }
    }

    /// Takes `stage`'s parameters as an artifact's header recorded them (what `stage` runs
    /// read from their inputs, so an export records the settings `run` would).
    pub fn take_recorded(&mut self, stage: StageId, recorded: &ciborium::Value) -> Result<()> {
        let unread = |e: ciborium::value::Error| {
            let ciborium::value::Error::Custom(problem) = e;
            anyhow!(
                "the {} artifact's recorded parameters do not read (made by another version of \
                 ossify?): {problem}",
                stage.name()
            )
        };
        match stage {
            StageId::MocapIo => self.mocap_io = recorded.deserialized().map_err(unread)?,
            StageId::Segment => self.segment = recorded.deserialized().map_err(unread)?,
            StageId::Jointfit => self.jointfit = recorded.deserialized().map_err(unread)?,
            StageId::Topo => self.topo = recorded.deserialized().map_err(unread)?,
            StageId::Bonefit => self.bonefit = recorded.deserialized().map_err(unread)?,
            StageId::Export => self.export = recorded.deserialized().map_err(unread)?,
        }
        Ok(())
    }

    /// The parameters set away from their defaults, as `stage.param` → value, every stage
    /// in pipeline order (what skeleton.json's `settings` records).
    pub fn changed(&self) -> Result<BTreeMap<String, Json>> {
        let defaults = Params::default();
        let mut out = BTreeMap::new();
        for stage in StageId::ALL {
            let (now, default) = (self.json(stage)?, defaults.json(stage)?);
            let (Some(now), Some(default)) = (now.as_object(), default.as_object()) else {
                continue;
            };
            for (name, value) in now {
                if default.get(name) != Some(value) {
                    out.insert(format!("{}.{name}", stage.name()), value.clone());
                }
            }
        }
        Ok(out)
    }

    /// A stage's parameters as JSON (for `params` and messages).
    pub fn json(&self, stage: StageId) -> Result<Json> {
        let v = match stage {
            StageId::MocapIo => serde_json::to_value(&self.mocap_io),
            StageId::Segment => serde_json::to_value(&self.segment),
            StageId::Jointfit => serde_json::to_value(&self.jointfit),
            StageId::Topo => serde_json::to_value(&self.topo),
            StageId::Bonefit => serde_json::to_value(&self.bonefit),
            StageId::Export => serde_json::to_value(&self.export),
        };
        v.with_context(|| format!("{}: parameters do not serialize", stage.name()))
    }
}

/// One stage's output.
pub enum Payload {
    /// mocap-io.
    Capture(Capture),
    /// segment.
    Segmentation(Segmentation),
    /// jointfit.
    PairFits(PairFits),
    /// topo.
    Topology(Topology),
    /// bonefit.
    Skeleton(Skeleton),
    /// export.
    Outputs(export::Outputs),
}

impl Payload {
    /// Writes the payload under a header as an artifact file, atomically and streamed (the
    /// bytes are never all in memory); returns their content hash.
    pub fn write(&self, path: &Path, header: &ArtifactHeader) -> Result<String> {
        let hash = match self {
            Payload::Capture(p) => artifact::write_hashed(path, header, p),
            Payload::Segmentation(p) => artifact::write_hashed(path, header, p),
            Payload::PairFits(p) => artifact::write_hashed(path, header, p),
            Payload::Topology(p) => artifact::write_hashed(path, header, p),
            Payload::Skeleton(p) => artifact::write_hashed(path, header, p),
            Payload::Outputs(p) => artifact::write_hashed(path, header, p),
        };
        Ok(hash?)
    }

    /// The content hash of the artifact [`Payload::write`] would write, without writing it.
    pub fn content_hash(&self, header: &ArtifactHeader) -> Result<String> {
        let hash = match self {
            Payload::Capture(p) => artifact::encoded_hash(header, p),
            Payload::Segmentation(p) => artifact::encoded_hash(header, p),
            Payload::PairFits(p) => artifact::encoded_hash(header, p),
            Payload::Topology(p) => artifact::encoded_hash(header, p),
            Payload::Skeleton(p) => artifact::encoded_hash(header, p),
            Payload::Outputs(p) => artifact::encoded_hash(header, p),
        };
        Ok(hash?)
    }

    /// A short domain summary (segment count, joints, files...).
    pub fn summary(&self) -> Json {
        match self {
            Payload::Capture(c) => {
                let t = &c.trajectories;
                json!({
                    "format": c.format.name(), "markers": t.markers(), "frames": t.frames(),
                    "frame_rate": t.frame_rate(), "missing_samples": t.missing_samples(),
                    "units_declared": c.info.declared_units, "warnings": c.info.warnings.len(),
                })
            }
            Payload::Segmentation(s) => json!({
                "segments": s.segments.len(),
                "markers_per_segment": s.segments.iter().map(|x| x.markers.len()).collect::<Vec<_>>(),
                "unassigned_markers": s.unassigned.len(),
                "sliding_markers": s.markers.iter().filter(|m| m.slides).count(),
            }),
            Payload::PairFits(f) => {
                let mut kinds = std::collections::BTreeMap::<String, usize>::new();
                for p in &f.pairs {
                    *kinds
                        .entry(format!("{:?}", p.kind).to_lowercase())
                        .or_default() += 1;
                }
                json!({
                    "frames": f.frames, "segments": f.poses.len(), "pairs": f.pairs.len(),
                    "kinds": kinds,
                    "methods": f.pairs.iter().map(|p| p.method.clone()).collect::<std::collections::BTreeSet<_>>(),
                })
            }
            Payload::Topology(t) => json!({
                "root_segment": t.root_segment,
                "joints": t.joints.len(),
                "edges": t.joints.iter().map(|j| format!("{} {}→{}", j.name, j.parent_segment, j.child_segment)).collect::<Vec<_>>(),
                "detached_segments": t.detached_segments,
            }),
            Payload::Skeleton(s) => json!({
                "frame_count": s.frame_count, "frame_rate": s.frame_rate,
                "root_segment": s.root_segment, "joints": s.joints.len(),
                "bone_lengths_mm": s.joints.iter()
                    .map(|j| (j.name.clone(), json!((j.bone_length * 10.0).round() / 10.0)))
                    .collect::<serde_json::Map<_, _>>(),
            }),
            Payload::Outputs(o) => json!({
                "files": o.files.iter().map(|(k, v)| (k.clone(), json!(v.len()))).collect::<serde_json::Map<_, _>>(),
            }),
        }
    }
}

/// Reads an artifact file as `stage`'s payload as it streams in (its bytes never all in
/// memory), checking the header's stage and schema; returns the file's content hash too.
pub fn read_payload(stage: StageId, path: &Path) -> Result<(ArtifactHeader, Payload, String)> {
    fn typed<P: serde::de::DeserializeOwned>(
        path: &Path,
        wrap: fn(P) -> Payload,
    ) -> Result<(ArtifactHeader, Payload, String)> {
        let (h, p, hash) = artifact::read_hashed::<P>(path)?;
        Ok((h, wrap(p), hash))
    }
    let (header, payload, hash) = match stage {
        StageId::MocapIo => typed(path, Payload::Capture)?,
        StageId::Segment => typed(path, Payload::Segmentation)?,
        StageId::Jointfit => typed(path, Payload::PairFits)?,
        StageId::Topo => typed(path, Payload::Topology)?,
        StageId::Bonefit => typed(path, Payload::Skeleton)?,
        StageId::Export => typed(path, Payload::Outputs)?,
    };
    check_stage(stage, &header, path)?;
    Ok((header, payload, hash))
}

/// Checks that an artifact's header names `stage` at its current schema version.
fn check_stage(stage: StageId, header: &ArtifactHeader, path: &Path) -> Result<()> {
    if header.stage != stage.name() || header.schema_version != stage.schema_version() {
        bail!(
            "{}: artifact of {} v{}, expected {} v{}",
            path.display(),
            header.stage,
            header.schema_version,
            stage.name(),
            stage.schema_version()
        );
    }
    Ok(())
}

/// The decoded artifacts of one pipeline run, as far as it got.
#[derive(Default)]
pub struct Products {
    /// mocap-io's output.
    pub capture: Option<Capture>,
    /// segment's output.
    pub segmentation: Option<Segmentation>,
    /// jointfit's output.
    pub fits: Option<PairFits>,
    /// topo's output.
    pub topology: Option<Topology>,
    /// bonefit's output.
    pub skeleton: Option<Skeleton>,
    /// export's output.
    pub outputs: Option<export::Outputs>,
}

fn need<T>(x: &Option<T>, stage: StageId) -> Result<&T> {
    x.as_ref().ok_or_else(|| {
        anyhow!(
            "the {} artifact is missing (give it with --in)",
            stage.name()
        )
    })
}

impl Products {
    /// Keeps a stage's output.
    pub fn put(&mut self, payload: Payload) {
        match payload {
            Payload::Capture(p) => self.capture = Some(p),
            Payload::Segmentation(p) => self.segmentation = Some(p),
            Payload::PairFits(p) => self.fits = Some(p),
            Payload::Topology(p) => self.topology = Some(p),
            Payload::Skeleton(p) => self.skeleton = Some(p),
            Payload::Outputs(p) => self.outputs = Some(p),
        }
    }

    /// Runs one stage on the products it needs. mocap-io reads `capture_file`.
    pub fn compute(
        &self,
        stage: StageId,
        params: &Params,
        capture_file: Option<&Path>,
    ) -> Result<Payload> {
        let capture = || need(&self.capture, StageId::MocapIo);
        let seg = || need(&self.segmentation, StageId::Segment);
        let fits = || need(&self.fits, StageId::Jointfit);
        let topology = || need(&self.topology, StageId::Topo);
        Ok(match stage {
            StageId::MocapIo => {
                let path = capture_file.ok_or_else(|| anyhow!("mocap-io needs a capture file"))?;
                Payload::Capture(mocap_io::read_capture(path, &params.mocap_io)?)
            }
            StageId::Segment => {
                Payload::Segmentation(segment::run(&capture()?.trajectories, &params.segment)?)
            }
            StageId::Jointfit => Payload::PairFits(jointfit::run(
                &capture()?.trajectories,
                seg()?,
                &params.jointfit,
            )?),
            StageId::Topo => Payload::Topology(topo::run(seg()?, fits()?, &params.topo)?),
            StageId::Bonefit => Payload::Skeleton(bonefit::run(
                &capture()?.trajectories,
                seg()?,
                fits()?,
                topology()?,
                &params.bonefit,
            )?),
            StageId::Export => {
                Payload::Outputs(self.with_export_inputs(params, |inputs| {
                    Ok(export::run(inputs, &params.export)?)
                })?)
            }
        })
    }

    /// Calls `f` with export's inputs: every earlier stage's output and the run's settings.
    pub fn with_export_inputs<R>(
        &self,
        params: &Params,
        f: impl FnOnce(&export::Inputs<'_>) -> Result<R>,
    ) -> Result<R> {
        let capture = need(&self.capture, StageId::MocapIo)?;
        let inputs = export::Inputs {
            trajectories: &capture.trajectories,
            segmentation: need(&self.segmentation, StageId::Segment)?,
            fits: need(&self.fits, StageId::Jointfit)?,
            topology: need(&self.topology, StageId::Topo)?,
            skeleton: need(&self.skeleton, StageId::Bonefit)?,
            settings: &params.changed()?,
            reader_warnings: &capture.info.warnings,
        };
        f(&inputs)
    }

    /// Runs export, each file written as it is made (see [`ExportSink`]) into `dir` and
    /// into the `artifact` (path, header) given; the artifact's writer comes back to be
    /// finished.
    pub fn export_to(
        &self,
        params: &Params,
        dir: Option<&Path>,
        artifact: Option<(&Path, &ArtifactHeader)>,
    ) -> Result<(Exported, Option<ByteMapWriter>)> {
        self.with_export_inputs(params, |inputs| {
            let writer = artifact.map(|(path, header)| {
                ByteMapWriter::create(
                    path,
                    header,
                    OUTPUTS_FIELD,
                    export::file_names(inputs).len(),
                )
            });
            let mut sink = ExportSink::new(dir, writer)?;
            // Writing (the output folder and the cache entry: twice the files' bytes) goes
            // on beside the making of the next file; one file waits between them at most.
            std::thread::scope(|scope| {
                let (to_writer, files) = std::sync::mpsc::sync_channel::<(String, Vec<u8>)>(1);
                let writing = scope.spawn(move || -> Result<ExportSink> {
                    for (name, bytes) in files {
                        sink.file(&name, bytes)?;
                    }
                    Ok(sink)
                });
                let made = export::run_each(inputs, &params.export, |name, bytes| {
                    // A send fails only where the writer stopped at an error, told below.
                    to_writer
                        .send((name.to_owned(), bytes))
                        .map_err(|_| anyhow!("the output writer stopped"))
                });
                drop(to_writer);
                let written = writing
                    .join()
                    .map_err(|_| anyhow!("the output writer panicked"))?;
                let sink = written?;
                made?;
                sink.finish()
            })
        })
    }
}

/// The field of export's artifact payload that holds its files (`export::Outputs::files`).
const OUTPUTS_FIELD: &str = "files";

/// What export wrote into an output folder.
#[derive(Debug)]
pub struct Exported {
    /// Every file of the set, in name order: written now, or left as it was where it
    /// already held these bytes (none when export wrote only an artifact).
    pub files: Vec<PathBuf>,
    /// skeleton.json's bytes (the run's findings are read from them).
    pub skeleton_json: Vec<u8>,
}

/// Export's files as they come: each to a temporary beside its place in the output folder,
/// if any (the set renamed into place only when all came, see [`artifact::FileSet`]; a
/// file already holding its bytes is left as it is), and into the export artifact being
/// written, if any; skeleton.json's bytes are kept. Only one file's bytes are in memory
/// at a time.
struct ExportSink {
    dir: Option<PathBuf>,
    set: FileSet,
    /// Every file of the folder, written now or already holding these bytes.
    files: Vec<PathBuf>,
    artifact: Option<ByteMapWriter>,
    skeleton_json: Option<Vec<u8>>,
}

impl ExportSink {
    fn new(dir: Option<&Path>, artifact: Option<ByteMapWriter>) -> Result<Self> {
        if let Some(dir) = dir {
            std::fs::create_dir_all(dir)
                .with_context(|| format!("{}: cannot create", dir.display()))?;
        }
        Ok(Self {
            dir: dir.map(Path::to_path_buf),
            set: FileSet::default(),
            files: Vec::new(),
            artifact,
            skeleton_json: None,
        })
    }

    fn file(&mut self, name: &str, bytes: Vec<u8>) -> Result<()> {
        check_output_name(name)?;
        if let Some(dir) = &self.dir {
            let path = dir.join(name);
            // A rerun into the same folder rewrites only what changed: writing (and
            // syncing) hundreds of megabytes again is most of a cached run's time.
            if !holds(&path, &bytes) {
                self.set.add(&path, &bytes)?;
            }
            self.files.push(path);
        }
        if let Some(artifact) = &mut self.artifact {
            artifact.push(name, &bytes)?;
        }
        if name == "skeleton.json" {
            self.skeleton_json = Some(bytes);
        }
        Ok(())
    }

    /// Renames the files into place; gives the artifact writer back to be finished.
    fn finish(self) -> Result<(Exported, Option<ByteMapWriter>)> {
        let skeleton_json = self
            .skeleton_json
            .context("the export stage wrote no skeleton.json")?;
        self.set.commit()?;
        Ok((
            Exported {
                files: self.files,
                skeleton_json,
            },
            self.artifact,
        ))
    }
}

/// True when `path` is a file holding exactly `bytes` (compared block by block).
fn holds(path: &Path, bytes: &[u8]) -> bool {
    use std::io::Read as _;
    let same_size =
        std::fs::metadata(path).is_ok_and(|m| m.is_file() && m.len() == bytes.len() as u64);
    let Some(mut file) = same_size.then(|| std::fs::File::open(path).ok()).flatten() else {
        return false;
    };
    let mut block = vec![0u8; 1 << 16];
    let mut at = 0;
    while at < bytes.len() {
        match file.read(&mut block) {
            Ok(n) if n > 0 && at + n <= bytes.len() && block[..n] == bytes[at..at + n] => {
                at += n;
            }
            _ => return false,
        }
    }
    true
}

/// Streams a cached export artifact's files into `dir` (each written as it is read, the
/// set renamed into place when all came), with its content hash; `None` where the entry
/// is damaged, changed since it was stored or does not match `expected`, the header it
/// should have (after a warning), or has no recorded hash (silently), so export runs
/// again. A file that cannot be written into `dir` is an error.
fn export_from_cache(
    path: &Path,
    expected: &ArtifactHeader,
    dir: &Path,
    progress: &Progress,
) -> Result<Option<(Exported, String)>> {
    let damaged = |e: &dyn std::fmt::Display| {
        progress.warn(&format!("damaged cache entry, recomputing: {e:#}"));
        Ok(None)
    };
    let (mut reader, header) = match ByteMapReader::open(path, OUTPUTS_FIELD) {
        Ok(opened) => opened,
        Err(e) => return damaged(&e),
    };
    if let Err(e) = check_stage(StageId::Export, &header, path) {
        return damaged(&e);
    }
    // The tool version may differ: the key deliberately leaves it out.
    if header.params != expected.params || header.inputs != expected.inputs {
        progress.warn(&format!(
            "{}: cache entry does not match its key (parameters or inputs differ); recomputing",
            path.display()
        ));
        return Ok(None);
    }
    if Cache::recorded_hash(path).is_none() {
        return Ok(None);
    }
    let mut sink = ExportSink::new(Some(dir), None)?;
    loop {
        match reader.next_entry() {
            Ok(Some((name, bytes))) => sink.file(&name, bytes)?,
            Ok(None) => break,
            Err(e) => return damaged(&e),
        }
    }
    let hash = match reader.finish() {
        Ok(hash) => hash,
        Err(e) => return damaged(&e),
    };
    // Checked once streamed: the files written so far go with the set if it differs.
    if !unchanged_since_stored(path, &hash, progress) {
        return Ok(None);
    }
    let (exported, _) = sink.finish()?;
    Ok(Some((exported, hash)))
}

/// What happened to one stage in a run.
#[derive(Clone, Debug, Serialize)]
pub struct StageRun {
    /// Stage name.
    pub name: &'static str,
    /// True when the artifact came from the cache.
    pub cached: bool,
    /// Wall time of the stage (computing, or loading and checking the cached entry).
    pub seconds: f64,
    /// Cache key of the run (the entry is `<cache>/<stage>-v<schema>/<key>.cbor`).
    #[serde(skip_serializing_if = "String::is_empty")]
    pub key: String,
    /// blake3 of the artifact's bytes.
    #[serde(rename = "blake3", skip_serializing_if = "String::is_empty")]
    pub hash: String,
}

/// The header a stage's artifact gets.
pub fn header(stage: StageId, params: &Params, inputs: Vec<InputHash>) -> Result<ArtifactHeader> {
    Ok(ArtifactHeader {
        stage: stage.name().to_string(),
        schema_version: stage.schema_version(),
        tool_version: TOOL_VERSION.to_string(),
        params: params.canonical(stage)?,
        inputs,
    })
}

/// Runs the whole pipeline on a capture file with the cache, and writes the output files
/// into `out` (as a set, only when every stage succeeded).
///
/// `force_from`: that stage and everything downstream are recomputed even when cached.
/// Returns the products, one [`StageRun`] per stage and what was written. A failing
/// stage's error names the stage and the capture file.
///
/// A cached stage's output is decoded only where a stage to compute reads it: a run whose
/// every stage is cached reads the headers and hashes of the entries and streams export's
/// files out, so its products hold nothing, and export's files are never among them (they
/// went to `out` one at a time, see [`ExportSink`]). An entry found damaged when decoded
/// has already keyed the stages after it by its hash, so the run starts over with that
/// stage recomputed.
pub fn run_cached(
    capture_file: &Path,
    params: &Params,
    cache: &Cache,
    force_from: Option<StageId>,
    progress: &Progress,
    out: &Path,
) -> Result<(Products, Vec<StageRun>, Exported)> {
    let file_bytes = std::fs::read(capture_file)
        .with_context(|| format!("{}: cannot read", capture_file.display()))?;
    let file_hash = artifact::content_hash(&file_bytes);
    drop(file_bytes);
    let mut distrusted = Vec::new();
    loop {
        let run = CachedRun {
            capture_file,
            file_hash: &file_hash,
            params,
            cache,
            force_from,
            progress,
            out,
        };
        match run.pass(&distrusted)? {
            Pass::Done(done) => return Ok(*done),
            // Each pass distrusts one more stage, so at most one pass per stage follows.
            Pass::Damaged(stage) => distrusted.push(stage),
        }
    }
}

/// How one pass of [`run_cached`] ended.
enum Pass {
    /// Every stage ran or came from the cache: the products, the runs, what was written.
    Done(Box<(Products, Vec<StageRun>, Exported)>),
    /// A stage's cache entry, taken by its header and hash, did not decode (or had
    /// changed) when a later stage needed it.
    Damaged(StageId),
}

/// What one pass of [`run_cached`] works with.
struct CachedRun<'a> {
    capture_file: &'a Path,
    file_hash: &'a str,
    params: &'a Params,
    cache: &'a Cache,
    force_from: Option<StageId>,
    progress: &'a Progress,
    out: &'a Path,
}

impl CachedRun<'_> {
    /// Runs every stage, recomputing `distrusted` ones and those `force_from` names.
    fn pass(&self, distrusted: &[StageId]) -> Result<Pass> {
        let (params, progress, capture_file) = (self.params, self.progress, self.capture_file);
        let mut products = Products::default();
        let mut runs: Vec<StageRun> = Vec::new();
        let mut exported = None;
        // Cached entries taken by header and hash, not decoded yet: (path, hash) by stage.
        let mut unread: BTreeMap<StageId, (PathBuf, String)> = BTreeMap::new();
        // What the reader said about the file often explains a later failure (every sample
        // flagged invalid, units guessed).
        let failed = |products: &Products, e: anyhow::Error, stage: StageId| {
            progress.abandon();
            if let Some(capture) = &products.capture {
                for w in &capture.info.warnings {
                    progress.warn(&format!("{}: {w}", capture_file.display()));
                }
            }
            e.context(format!(
                "stage {} failed on {}",
                stage.name(),
                capture_file.display()
            ))
        };
        for stage in StageId::ALL {
            let start = Instant::now();
            progress.start(stage.name());
            let inputs: Vec<InputHash> = if stage == StageId::MocapIo {
                vec![InputHash {
                    role: CAPTURE_ROLE.into(),
                    blake3: self.file_hash.to_owned(),
                }]
            } else {
                stage
                    .inputs()
                    .iter()
                    .map(|up| InputHash {
                        role: up.name().into(),
                        blake3: runs[*up as usize].hash.clone(),
                    })
                    .collect()
            };
            let header = header(stage, params, inputs)?;
            let key = cache::cache_key(
                stage.name(),
                stage.schema_version(),
                &cache::encode(&header.params),
                &header.inputs,
            );
            let trusted = self.force_from.is_none_or(|f| stage < f) && !distrusted.contains(&stage);
            let entry = self
                .cache
                .entry_path(stage.name(), stage.schema_version(), &key);
            let (cached, hash) = if stage == StageId::Export {
                // The files go straight to `out`, from the cache or as export makes them.
                let hit = if trusted && entry.exists() {
                    export_from_cache(&entry, &header, self.out, progress)?
                } else {
                    None
                };
                let (files, cached, hash) = match hit {
                    Some((files, hash)) => (files, true, hash),
                    None => {
                        if let Some(damaged) =
                            read_unread(&mut products, stage.inputs(), &mut unread, progress)
                        {
                            return Ok(Pass::Damaged(damaged));
                        }
                        let (files, writer) = products
                            .export_to(params, Some(self.out), Some((&entry, &header)))
                            .map_err(|e| failed(&products, e, stage))?;
                        let writer = writer.context("export's artifact writer went missing")?;
                        let (hash, written) = writer.finish();
                        match written {
                            Ok(()) => record_hash(&entry, &hash, progress),
                            Err(e) => progress.warn(&format!("not cached: {e:#}")),
                        }
                        (files, false, hash)
                    }
                };
                exported = Some(files);
                (cached, hash)
            } else {
                let hit = if trusted {
                    peek_checked(&entry, stage, &header, progress)
                } else {
                    None
                };
                match hit {
                    Some(hash) => {
                        unread.insert(stage, (entry, hash.clone()));
                        (true, hash)
                    }
                    None => {
                        if let Some(damaged) =
                            read_unread(&mut products, stage.inputs(), &mut unread, progress)
                        {
                            return Ok(Pass::Damaged(damaged));
                        }
                        let payload = products
                            .compute(stage, params, Some(capture_file))
                            .map_err(|e| failed(&products, e, stage))?;
                        let hash = match payload.write(&entry, &header) {
                            Ok(hash) => {
                                record_hash(&entry, &hash, progress);
                                hash
                            }
                            Err(e) => {
                                progress.warn(&format!("not cached: {e:#}"));
                                payload.content_hash(&header)?
                            }
                        };
                        products.put(payload);
                        (false, hash)
                    }
                }
            };
            let seconds = start.elapsed().as_secs_f64();
            progress.finish();
            runs.push(StageRun {
                name: stage.name(),
                cached,
                seconds,
                key,
                hash,
            });
        }
        let exported = exported.context("the export stage did not run")?;
        Ok(Pass::Done(Box::new((products, runs, exported))))
    }
}

/// A cache entry's content hash, its header checked against the one it should have and
/// its hash against the one recorded when it was stored, its payload left undecoded (see
/// [`read_unread`]); `None` when there is no usable entry (after a warning for a damaged,
/// changed or foreign one; silently for one with no recorded hash).
fn peek_checked(
    path: &Path,
    stage: StageId,
    expected: &ArtifactHeader,
    progress: &Progress,
) -> Option<String> {
    if !path.exists() {
        return None;
    }
    let checked = artifact::read_header_hashed(path)
        .map_err(anyhow::Error::from)
        .and_then(|(header, hash)| check_stage(stage, &header, path).map(|()| (header, hash)));
    match checked {
        // The tool version may differ: the key deliberately leaves it out.
        Ok((header, hash))
            if header.params == expected.params && header.inputs == expected.inputs =>
        {
            unchanged_since_stored(path, &hash, progress).then_some(hash)
        }
        Ok(_) => {
            progress.warn(&format!(
                "{}: cache entry does not match its key (parameters or inputs differ); recomputing",
                path.display()
            ));
            None
        }
        Err(e) => {
            progress.warn(&format!("damaged cache entry, recomputing: {e:#}"));
            None
        }
    }
}

/// Records a stored entry's content hash; where that fails the entry will be recomputed
/// next time (it has no record), which is worth a warning, not a failed run.
fn record_hash(entry: &Path, hash: &str, progress: &Progress) {
    if let Err(e) = Cache::record_hash(entry, hash) {
        progress.warn(&format!("not cached: {e:#}"));
    }
}

/// True when `entry`'s content hash is the one recorded when it was stored; false (after
/// a warning where a different one was recorded) otherwise.
fn unchanged_since_stored(entry: &Path, hash: &str, progress: &Progress) -> bool {
    match Cache::recorded_hash(entry) {
        Some(recorded) if recorded == hash => true,
        Some(_) => {
            progress.warn(&format!(
                "damaged cache entry, recomputing: {}: its content differs from what was \
                 stored (blake3 {hash})",
                entry.display()
            ));
            false
        }
        None => false,
    }
}

/// Decodes the cached outputs of `stages` that are still unread into `products`. The
/// first that does not decode, or whose file no longer has the hash it was taken with,
/// is returned (after a warning): it keyed later stages, so the run must start over.
fn read_unread(
    products: &mut Products,
    stages: &[StageId],
    unread: &mut BTreeMap<StageId, (PathBuf, String)>,
    progress: &Progress,
) -> Option<StageId> {
    for &stage in stages {
        let Some((path, hash)) = unread.remove(&stage) else {
            continue;
        };
        let problem = match read_payload(stage, &path) {
            Ok((_, payload, read)) if read == hash => {
                products.put(payload);
                continue;
            }
            Ok(_) => format!("{}: changed while this run read it", path.display()),
            Err(e) => format!("{e:#}"),
        };
        progress.warn(&format!("damaged cache entry, recomputing: {problem}"));
        progress.abandon();
        return Some(stage);
    }
    None
}

/// Runs segment → export in memory on a capture already read (no cache, no files).
///
/// Returns the products and the time of each stage (mocap-io not included).
pub fn run_in_memory(capture: Capture, params: &Params) -> Result<(Products, Vec<StageRun>)> {
    run_in_memory_with(capture, params, |_| {})
}

/// As [`run_in_memory`], with `adjust` applied to the segmentation before the later stages
/// read it (eval's `--true-segments` puts the true groups there).
pub fn run_in_memory_with(
    capture: Capture,
    params: &Params,
    adjust: impl FnOnce(&mut segment::Segmentation),
) -> Result<(Products, Vec<StageRun>)> {
    let mut products = Products {
        capture: Some(capture),
        ..Products::default()
    };
    let mut runs = Vec::new();
    let mut adjust = Some(adjust);
    for stage in &StageId::ALL[1..] {
        let start = Instant::now();
        let mut payload = products
            .compute(*stage, params, None)
            .with_context(|| format!("stage {} failed", stage.name()))?;
        if let Payload::Segmentation(seg) = &mut payload
            && let Some(adjust) = adjust.take()
        {
            adjust(seg);
        }
        products.put(payload);
        runs.push(StageRun {
            name: stage.name(),
            cached: false,
            seconds: start.elapsed().as_secs_f64(),
            key: String::new(),
            hash: String::new(),
        });
    }
    Ok((products, runs))
}

/// Checks that an output file name is a plain name (export chooses it; we write it).
pub fn check_output_name(name: &str) -> Result<()> {
    let plain = !name.is_empty()
        && name != "."
        && name != ".."
        && !name.contains(['/', '\\'])
        && !name.starts_with('.');
    if plain {
        Ok(())
    } else {
        bail!("export produced a file named {name:?}, which is not a plain file name")
    }
}

#[cfg(test)]
mod tests {
    use std::collections::BTreeMap;

    use super::*;
    use crate::tempdir::TempDir;

    /// Writes `outputs` into `dir` through export's sink, as a run writes them.
    fn write_outputs(outputs: &export::Outputs, dir: &Path) -> Result<Vec<PathBuf>> {
        let mut sink = ExportSink::new(Some(dir), None)?;
        for (name, bytes) in &outputs.files {
            sink.file(name, bytes.clone())?;
        }
        Ok(sink.finish()?.0.files)
    }

    fn outputs(tag: &str) -> export::Outputs {
        let files: BTreeMap<String, Vec<u8>> = ["joints.csv", "skeleton.bvh", "skeleton.json"]
            .into_iter()
            .map(|n| (n.to_string(), format!("{tag} {n}").into_bytes()))
            .collect();
        export::Outputs { files }
    }

    #[test]
    fn settings_are_the_parameters_set_away_from_their_defaults() {
        assert!(Params::default().changed().unwrap().is_empty());
        let set = Params::from_assignments(&[
            r#"segment.groups=[["A", "B"]]"#.into(),
            "topo.root=LASI".into(),
            "jointfit.min_frames=30".into(), // its default: not a setting
        ])
        .unwrap();
        let changed = set.changed().unwrap();
        assert_eq!(
            changed.keys().collect::<Vec<_>>(),
            ["segment.groups", "topo.root"]
        );
        assert_eq!(changed["segment.groups"], serde_json::json!([["A", "B"]]));
        assert_eq!(changed["topo.root"], serde_json::json!("LASI"));
    }

    #[test]
    fn outputs_are_replaced_as_a_set_or_not_at_all() {
        let dir = TempDir::new("outputs").unwrap();
        let out = dir.path().join("out");
        write_outputs(&outputs("old"), &out).unwrap();
        let read = |n: &str| std::fs::read_to_string(out.join(n)).unwrap();
        assert_eq!(read("skeleton.bvh"), "old skeleton.bvh");

        // skeleton.json (last in name order) cannot be written: a folder is in the way.
        std::fs::remove_file(out.join("skeleton.json")).unwrap();
        std::fs::create_dir(out.join("skeleton.json")).unwrap();
        let err = write_outputs(&outputs("new"), &out).unwrap_err();
        assert!(format!("{err:#}").contains("skeleton.json"), "{err:#}");
        // Nothing of the new set landed, and no temporary file is left behind.
        assert_eq!(read("joints.csv"), "old joints.csv");
        assert_eq!(read("skeleton.bvh"), "old skeleton.bvh");
        let mut names: Vec<String> = std::fs::read_dir(&out)
            .unwrap()
            .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
            .collect();
        names.sort();
        assert_eq!(names, ["joints.csv", "skeleton.bvh", "skeleton.json"]);

        // With the folder gone the new set is written whole.
        std::fs::remove_dir(out.join("skeleton.json")).unwrap();
        write_outputs(&outputs("new"), &out).unwrap();
        assert_eq!(read("skeleton.bvh"), "new skeleton.bvh");
        assert_eq!(read("skeleton.json"), "new skeleton.json");

        // Written again, a file already holding its bytes is left as it is (same inode),
        // one that differs is replaced, and every file is listed either way.
        #[cfg(unix)]
        {
            use std::os::unix::fs::MetadataExt as _;
            let inode = |n: &str| std::fs::metadata(out.join(n)).unwrap().ino();
            let before = (inode("joints.csv"), inode("skeleton.bvh"));
            let mut again = outputs("new");
            again
                .files
                .insert("skeleton.bvh".into(), b"newer skeleton.bvh".to_vec());
            let listed = write_outputs(&again, &out).unwrap();
            assert_eq!(listed.len(), 3);
            assert_eq!(inode("joints.csv"), before.0);
            assert_ne!(inode("skeleton.bvh"), before.1);
            assert_eq!(read("skeleton.bvh"), "newer skeleton.bvh");
        }
    }
}
