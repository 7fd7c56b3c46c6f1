//! `cargo xtask run`: a capture in, skeleton files out, every stage cached.

use std::path::{Path, PathBuf};

use anyhow::{Context as _, Result, bail};
use serde_json::json;

use crate::cache::{self, Cache};
use crate::pipeline::{self, Params, StageId, StageRun};
use crate::progress::Progress;

/// The bundled input used when `run` gets none (relative to the project root).
pub const DEFAULT_INPUT: &str = "fixtures/human-clean.c3d";

/// Arguments of `run`.
#[derive(clap::Args)]
#[command(after_help = "\
Stages: mocap-io, segment, jointfit, topo, bonefit, export. Each stage's artifact is cached \
under <cache>/<stage>-v<schema>/<key>.cbor, keyed by the stage, its schema version, its \
parameters and its inputs' content hashes: a rerun recomputes only what changed and what \
is downstream of it. Output files are written only when every stage succeeded, each \
atomically. `cargo xtask params` lists every STAGE.PARAM.")]
#[derive(Clone)]
pub struct Args {
    /// Capture files (C3D, TRC, CSV: ossify's, Motive's or Nexus's; QTM's TSV) or folders
    /// of them [default: fixtures/human-clean.c3d]. More than one capture, or a folder, is
    /// a batch: each capture's files go to <out>/<its stem>/, a capture that fails does not
    /// stop the others, and the exit status says whether any failed.
    pub input: Vec<PathBuf>,
    /// Output folder [default: out/<input stem>/; for a batch, the folder that receives
    /// one folder per capture, default out/].
    #[arg(long, value_name = "DIR")]
    pub out: Option<PathBuf>,
    /// Set a stage parameter, e.g. jointfit.alpha=0.25 or jointfit.method=aguiar
    /// (VALUE is JSON if it parses, else a string). Repeatable.
    #[arg(long = "set", value_name = "STAGE.PARAM=VALUE")]
    pub set: Vec<String>,
    /// Take the parameters a file records: a JSON object of "STAGE.PARAM": value, or a
    /// skeleton.json (its settings, to rerun as it was made); --set applies after it.
    #[arg(long, value_name = "FILE")]
    pub settings: Option<PathBuf>,
    /// Recompute this stage and everything downstream, even when cached.
    #[arg(long, value_name = "STAGE")]
    pub from: Option<String>,
    /// Recompute every stage (the cache is still refreshed).
    #[arg(long)]
    pub force: bool,
    /// Print a JSON report on stdout (stages, cache hits, seconds, outputs).
    #[arg(long)]
    pub json: bool,
    /// Cache folder [default: $OSSIFY_CACHE, else <project root>/.cache/ossify].
    #[arg(long, value_name = "DIR")]
    pub cache: Option<PathBuf>,
}

/// What a run did.
#[derive(Debug)]
pub struct Report {
    /// One entry per stage, in pipeline order.
    pub stages: Vec<StageRun>,
    /// Output folder.
    pub out: PathBuf,
    /// Segments found: this body's, where the capture holds several.
    pub segments: usize,
    /// Joints in the tree.
    pub joints: usize,
    /// The output files: written, or left as they were where they held their bytes.
    pub files: Vec<PathBuf>,
    /// What the reader warned about the capture (units guessed, points not read, ...).
    pub warnings: Vec<String>,
    /// What skeleton.json says deserves a look: joint warnings, unassigned and sliding
    /// markers, detached segments, the topology's remarks.
    pub findings: Vec<String>,
    /// Where the capture holds several bodies (skeleton.json's `bodies`), each other body's
    /// run, its files in `<out>/<body name>/`.
    pub other_bodies: Vec<Report>,
}

impl Report {
    /// The `--json` object.
    pub fn json(&self) -> serde_json::Value {
        json!({
            "stages": self.stages,
            "out": self.out,
            "segments": self.segments,
            "joints": self.joints,
            "files": self.files,
            "warnings": self.warnings,
            "findings": self.findings,
            "other_bodies": self.other_bodies.iter().map(Report::json).collect::<Vec<_>>(),
        })
    }
}

/// Runs `run`: one capture, or a batch (see [`Args::input`]).
pub fn main(args: &Args) -> Result<()> {
    let Some(batch) = batch(args)? else {
        let report = execute(args, &Progress::stderr())?;
        print_report(&report);
        if args.json {
            println!("{}", serde_json::to_string_pretty(&report.json())?);
        }
        return Ok(());
    };
    // A bad --set would fail every capture alike: say so once, before any runs.
    run_params(args)?;
    let mut failed: Vec<String> = Vec::new();
    let mut reports: Vec<serde_json::Value> = Vec::new();
    for (input, out) in &batch {
        eprintln!("== {}", input.display());
        let one = Args {
            input: vec![input.clone()],
            out: Some(out.clone()),
            ..args.clone()
        };
        match execute(&one, &Progress::stderr()) {
            Ok(report) => {
                print_report(&report);
                reports.push(json!({"input": input, "report": report.json()}));
            }
            Err(e) => {
                eprintln!("error: {e:#}");
                failed.push(input.display().to_string());
                reports.push(json!({"input": input, "error": format!("{e:#}")}));
            }
        }
    }
    if args.json {
        println!("{}", serde_json::to_string_pretty(&reports)?);
    }
    eprintln!(
        "{} captures: {} written, {} failed",
        batch.len(),
        batch.len() - failed.len(),
        failed.len()
    );
    if !failed.is_empty() {
        bail!(
            "{} of {} captures failed: {}",
            failed.len(),
            batch.len(),
            failed.join(", ")
        );
    }
    Ok(())
}

/// Warnings, then the summary (and each other body's), on stderr.
fn print_report(report: &Report) {
    for w in &report.warnings {
        eprintln!("warning: {w}");
    }
    eprintln!("{}", summary(report));
    for body in &report.other_bodies {
        eprintln!("{}", summary_with(body, false));
    }
}

/// The captures of a batch with each one's output folder, or `None` for a single capture
/// (one file given, or none). A folder gives its capture files (those whose extension
/// `mocap_io::detect_format` knows; not its subfolders), in name order; two captures
/// with one stem would write one folder, so that is an error named before anything runs.
fn batch(args: &Args) -> Result<Option<Vec<(PathBuf, PathBuf)>>> {
    if args.input.len() <= 1 && !args.input.iter().any(|p| p.is_dir()) {
        return Ok(None);
    }
    let mut captures: Vec<PathBuf> = Vec::new();
    for path in &args.input {
        if path.is_dir() {
            let mut found: Vec<PathBuf> = std::fs::read_dir(path)
                .with_context(|| format!("{}: cannot list the folder", path.display()))?
                .filter_map(|e| e.ok().map(|e| e.path()))
                .filter(|p| p.is_file() && mocap_io::detect_format(p, &[]).is_some())
                .collect();
            if found.is_empty() {
                bail!(
                    "{}: no C3D, TRC, CSV or TSV file in this folder",
                    path.display()
                );
            }
            found.sort();
            captures.extend(found);
        } else {
            captures.push(path.clone());
        }
    }
    let root = args.out.clone().unwrap_or_else(|| PathBuf::from("out"));
    let mut by_stem: std::collections::BTreeMap<String, &PathBuf> = Default::default();
    let mut batch = Vec::with_capacity(captures.len());
    for input in &captures {
        let stem = stem_of(input);
        if let Some(first) = by_stem.insert(stem.clone(), input) {
            bail!(
                "{} and {} would both write {}: run them separately with --out, or rename one",
                first.display(),
                input.display(),
                root.join(&stem).display()
            );
        }
        batch.push((input.clone(), root.join(stem)));
    }
    Ok(Some(batch))
}

/// A capture's file name without its extension ("capture" if it has none).
fn stem_of(input: &Path) -> String {
    input
        .file_stem()
        .map_or_else(|| "capture".into(), |s| s.to_string_lossy().into_owned())
}

/// The input a run reads: the argument, or the bundled fixture.
pub fn input_path(input: Option<&Path>) -> PathBuf {
    input.map_or_else(
        || crate::project_root().join(DEFAULT_INPUT),
        Path::to_path_buf,
    )
}

/// The run's parameters: the defaults, then `--settings`' file, then each `--set`.
fn run_params(args: &Args) -> Result<Params> {
    let mut params = match &args.settings {
        Some(path) => Params::from_assignments(&settings_file(path)?)
            .with_context(|| format!("--settings {}", path.display()))?,
        None => Params::default(),
    };
    for text in &args.set {
        params.set(&crate::set_param::parse_assignment(text)?)?;
    }
    Ok(params)
}

/// The assignments a settings file records, as `STAGE.PARAM=VALUE` (VALUE as JSON): the
/// file is a JSON object of `"STAGE.PARAM": value`, or a skeleton.json, whose `settings`
/// are that object.
pub(crate) fn settings_file(path: &Path) -> Result<Vec<String>> {
    let text = std::fs::read_to_string(path)
        .with_context(|| format!("--settings {}: cannot read it", path.display()))?;
    let json: serde_json::Value = serde_json::from_str(&text)
        .with_context(|| format!("--settings {}: not JSON", path.display()))?;
    let object = match json.get("settings") {
        Some(settings) if json.get("joints").is_some() => settings,
        _ => &json,
    };
    let Some(object) = object.as_object() else {
        bail!(
            "--settings {}: expected a JSON object of \"STAGE.PARAM\": value, or a \
             skeleton.json",
            path.display()
        );
    };
    Ok(object
        .iter()
        .map(|(name, value)| format!("{name}={value}"))
        .collect())
}

/// Runs the pipeline on one capture (the first input, or the bundled fixture) and writes
/// the outputs, without printing the summary.
pub fn execute(args: &Args, progress: &Progress) -> Result<Report> {
    let input = input_path(args.input.first().map(PathBuf::as_path));
    if !input.is_file() {
        bail!("{}: no such capture file", input.display());
    }
    let params = run_params(args)?;
    let mut force_from = args.from.as_deref().map(StageId::from_name).transpose()?;
    if args.force {
        force_from = Some(StageId::MocapIo);
    }
    let out = match &args.out {
        Some(dir) => dir.clone(),
        None => PathBuf::from("out").join(stem_of(&input)),
    };
    let cache = Cache::open(&cache::resolve_root(args.cache.as_deref()))?;
    let (mut report, document) = run_body(&input, &params, &cache, force_from, progress, &out)?;
    // Every other body from the same cached stages up to topo, which builds its tree.
    let force_from = force_from.map(|stage| stage.max(StageId::Topo));
    for body in &document.bodies {
        if document.body.as_ref() == Some(&body.name) || document.is_room(body) {
            continue;
        }
        let mut body_params = params.clone();
        body_params.topo.root = None;
        body_params.topo.body = body.segments.first().map(|&s| topo::SegmentRef::Id(s));
        let body_out = out.join(&body.name);
        let (body_report, _) = run_body(
            &input,
            &body_params,
            &cache,
            force_from,
            progress,
            &body_out,
        )?;
        report.other_bodies.push(body_report);
    }
    Ok(report)
}

/// Runs the pipeline on `input` with `params` into `out`: the report (no other bodies)
/// and the skeleton.json it wrote.
fn run_body(
    input: &Path,
    params: &Params,
    cache: &Cache,
    force_from: Option<StageId>,
    progress: &Progress,
    out: &Path,
) -> Result<(Report, export::SkeletonJson)> {
    let (_, stages, exported) =
        pipeline::run_cached(input, params, cache, force_from, progress, out)?;
    // The counts and the reader's warnings come from skeleton.json: a run served from the
    // cache decodes no stage's output.
    let document: export::SkeletonJson =
        serde_json::from_slice(&exported.skeleton_json).context("reading back skeleton.json")?;
    // Where the capture holds several bodies, this run's own: a prop's run is one segment.
    let segments = document
        .bodies
        .iter()
        .find(|b| document.body.as_ref() == Some(&b.name))
        .map_or(document.segments.len(), |b| b.segments.len());
    let report = Report {
        stages,
        out: out.to_path_buf(),
        segments,
        joints: document.joints.len(),
        files: exported.files,
        findings: findings(&document, params.jointfit.max_spin_deg),
        warnings: document
            .reader_warnings
            .iter()
            .map(|w| format!("{}: {w}", input.display()))
            .collect(),
        other_bodies: Vec::new(),
    };
    Ok((report, document))
}

/// Most markers named in one finding line; the rest are counted.
const NAMED_MARKERS: usize = 6;

/// `count` and `noun`, the noun plural but for one ("1 segment", "3 joints").
fn counted(count: usize, noun: &str) -> String {
    if count == 1 {
        format!("1 {noun}")
    } else {
        format!("{count} {noun}s")
    }
}

/// Other bodies listed a line each; more share one line (a capture with many props).
const MOST_BODIES_LISTED: usize = 3;

/// What a user should look at in `document`, one line each (empty when all is well);
/// segments whose spin is known less well than `spin_limit_deg` (jointfit's
/// `max_spin_deg`; 0 = not listed) are among it.
pub fn findings(document: &export::SkeletonJson, spin_limit_deg: f64) -> Vec<String> {
    // Where the capture holds several bodies, each body's files say what concerns its own
    // markers and segments, and the biggest body's what concerns the whole capture.
    let own = document
        .bodies
        .iter()
        .find(|b| document.body.as_ref() == Some(&b.name))
        .map(|b| b.segments.as_slice());
    let mine = |segment: Option<usize>| own.is_none_or(|o| segment.is_some_and(|s| o.contains(&s)));
    let whole_capture = document
        .bodies
        .first()
        .is_none_or(|b| document.body.as_ref() == Some(&b.name));
    let mut out = Vec::new();
    for j in &document.joints {
        for w in &j.warnings {
            out.push(format!(
                "joint {} (segment {} → {}): {w}",
                j.name, j.parent_segment, j.child_segment
            ));
        }
    }
    let listed = |what: &str, names: Vec<String>| {
        let shown: Vec<&str> = names
            .iter()
            .take(NAMED_MARKERS)
            .map(String::as_str)
            .collect();
        let more = names.len().saturating_sub(NAMED_MARKERS);
        let tail = if more > 0 {
            format!(" and {more} more")
        } else {
            String::new()
        };
        format!("{what}: {} — {}{tail}", names.len(), shown.join("; "))
    };
    let unassigned: Vec<String> = document
        .markers
        .iter()
        .filter(|m| m.segment.is_none())
        .map(|m| match &m.unassigned_reason {
            // The reasons carry parentheses of their own: "visible in 0 of 180 frames
            // (needs 10)".
            Some(why) => format!("{}: {why}", m.label),
            None => m.label.clone(),
        })
        .collect();
    if whole_capture && !unassigned.is_empty() {
        out.push(listed("markers in no segment", unassigned));
    }
    let sliding: Vec<String> = document
        .markers
        .iter()
        .filter(|m| m.slides && mine(m.segment))
        .map(|m| m.label.clone())
        .collect();
    if !sliding.is_empty() {
        out.push(listed(
            "markers sliding against their segment (skin or a loose marker)",
            sliding,
        ));
    }
    let glitching: Vec<String> = document
        .markers
        .iter()
        .filter(|m| m.glitch_frames > 0 && mine(m.segment))
        .map(|m| format!("{} ({})", m.label, export::frame_count(m.glitch_frames)))
        .collect();
    if !glitching.is_empty() {
        out.push(listed(
            "markers that left their partners in some frames (jumped off, or fell off and lay \
             still; those samples read as gaps)",
            glitching,
        ));
    }
    let swaps: Vec<String> = document
        .label_swaps
        .iter()
        .map(|s| {
            let frames: Vec<String> = s
                .frames
                .iter()
                .map(|[a, b]| {
                    let first = document.first_frame + *a as i64;
                    let last = document.first_frame + *b as i64;
                    format!("{first}–{last}")
                })
                .collect();
            format!(
                "{} ↔ {} in frames {}",
                s.markers[0],
                s.markers[1],
                frames.join(", ")
            )
        })
        .collect();
    if whole_capture && !swaps.is_empty() {
        out.push(listed(
            "label swaps found and undone (trajectories exchanged; frames as in the capture)",
            swaps,
        ));
    }
    let loose: Vec<String> = document
        .segments
        .iter()
        .filter(|s| mine(Some(s.id)))
        .filter_map(|s| {
            let spin = s
                .spin_deg
                .filter(|&d| spin_limit_deg > 0.0 && d > spin_limit_deg)?;
            let spin = if spin >= jointfit::SPIN_UNFIXED_DEG {
                "turn not fixed".to_string()
            } else {
                format!("±{spin:.0}°")
            };
            Some(format!("{} ({spin}: {})", s.id, s.markers.join(", ")))
        })
        .collect();
    if !loose.is_empty() {
        out.push(format!(
            "segments whose markers nearly line up, so their turn about that line is poorly \
             known (posed through a joint where one fits; a marker off the line would fix \
             it): {}",
            loose.join("; ")
        ));
    }
    let loose_groups = named_groups_not_rigid(document);
    if whole_capture && !loose_groups.is_empty() {
        out.push(format!(
            "segments segment.groups named whose markers do not keep their distances as one \
             body's do (check each group: markers across a joint, or a wrong label?): {}",
            loose_groups.join("; ")
        ));
    }
    let near: Vec<String> = document
        .segments
        .iter()
        .filter(|s| mine(Some(s.id)))
        .filter_map(|s| {
            let n = s.near_joint.as_ref()?;
            Some(format!(
                "{} (rotation z {:.1}, travel z {:.1}: {} | {})",
                s.id,
                n.rotation_z,
                n.travel_z,
                n.parts[0].join(", "),
                n.parts[1].join(", ")
            ))
        })
        .collect();
    if !near.is_empty() {
        out.push(format!(
            "segments that may be two turning little about a joint (the joint test came near \
             cutting them where shown; skin can hide such a joint; where it is two, \
             --set 'segment.groups=[[\"LABEL\", ...]]' makes a part a segment): {}",
            near.join("; ")
        ));
    }
    let others: Vec<&export::BodyJson> = document
        .bodies
        .iter()
        .filter(|b| document.body.as_ref() != Some(&b.name))
        .collect();
    // Beside many props, one line for the other bodies rather than one each.
    let movers: Vec<&&export::BodyJson> = others.iter().filter(|b| !document.is_room(b)).collect();
    if movers.len() > MOST_BODIES_LISTED {
        let each: Vec<String> = movers
            .iter()
            .map(|b| {
                format!(
                    "{} ({}, {})",
                    b.name,
                    counted(b.segments.len(), "segment"),
                    counted(b.marker_count, "marker")
                )
            })
            .collect();
        out.push(format!(
            "{} other bodies, each a skeleton of its own (no pair between it and this tree \
             fits a joint): {}",
            movers.len(),
            each.join("; ")
        ));
    }
    for b in &others {
        if !document.is_room(b) && movers.len() > MOST_BODIES_LISTED {
            continue;
        }
        if document.is_room(b) {
            if whole_capture {
                let still: Vec<String> = document
                    .stationary_markers()
                    .into_iter()
                    .map(str::to_owned)
                    .collect();
                out.push(listed(
                    "markers that never move (the room's: floor or reference markers, stray \
                     reflections), a segment of their own in no skeleton",
                    still,
                ));
            }
            continue;
        }
        out.push(format!(
            "another body, {}: {}, {}, a skeleton of its own (no pair between it and this \
             tree fits a joint)",
            b.name,
            counted(b.segments.len(), "segment"),
            counted(b.marker_count, "marker")
        ));
    }
    let detached: Vec<usize> = document
        .detached_segments
        .iter()
        .copied()
        .filter(|s| !others.iter().any(|b| b.segments.contains(s)))
        .collect();
    if !detached.is_empty() {
        out.push(format!("segments not in the tree: {detached:?}"));
    }
    out.extend(document.notes.iter().map(|n| format!("topology: {n}")));
    out
}

/// A named segment is worth a look when its markers' median rigidity residual is at least
/// this many times the median segment's: a correctly named segment sits among the others
/// (hexapod-hard-s20001's six named coxae: at most 1.84 times), one spanning a joint does
/// not (human-hard-s5's left thigh and shank named as one, 480 frames: 6.49 times).
const NAMED_LOOSE_RATIO: f64 = 3.0;

/// The segments `segment.groups` named that fit as one body clearly worse than the
/// capture's segments do, as "id (median rigidity residual, times the median segment's)".
fn named_groups_not_rigid(document: &export::SkeletonJson) -> Vec<String> {
    let by_label: std::collections::HashMap<&str, f64> = document
        .markers
        .iter()
        .filter_map(|m| Some((m.label.as_str(), m.rigidity_residual_mm?)))
        .filter(|(_, r)| r.is_finite())
        .collect();
    let residual = |label: &String| by_label.get(label.as_str()).copied();
    let median = |mut v: Vec<f64>| {
        v.sort_by(f64::total_cmp);
        v.get(v.len() / 2).copied()
    };
    let per_segment: Vec<(usize, bool, f64)> = document
        .segments
        .iter()
        .filter_map(|s| {
            let r = median(s.markers.iter().filter_map(residual).collect())?;
            Some((s.id, s.named, r))
        })
        .collect();
    let Some(typical) = median(per_segment.iter().map(|s| s.2).collect()).filter(|&t| t > 0.0)
    else {
        return Vec::new();
    };
    per_segment
        .iter()
        .filter(|&&(_, named, r)| named && r >= NAMED_LOOSE_RATIO * typical)
        .map(|&(id, _, r)| {
            format!(
                "{id} ({r:.1} mm median rigidity residual, {:.1} times the median segment's \
                 {typical:.1} mm)",
                r / typical
            )
        })
        .collect()
}

/// The end-of-run summary for stderr.
pub fn summary(report: &Report) -> String {
    summary_with(report, true)
}

/// [`summary`], with a line per stage where `stage_lines` (another body's run shares the
/// first run's stages up to topo, so its table says little but "cached").
fn summary_with(report: &Report, stage_lines: bool) -> String {
    let hits = report.stages.iter().filter(|s| s.cached).count();
    let total: f64 = report.stages.iter().map(|s| s.seconds).sum();
    let mut text = format!(
        "{}, {}; {hits}/{} stages from the cache; {total:.2} s\n",
        counted(report.segments, "segment"),
        counted(report.joints, "joint"),
        report.stages.len()
    );
    for s in report.stages.iter().filter(|_| stage_lines) {
        text.push_str(&format!(
            "  {:<9} {:>8.3} s  {}\n",
            s.name,
            s.seconds,
            if s.cached { "cached" } else { "computed" }
        ));
    }
    text.push_str(&format!("wrote {}:", report.out.display()));
    for f in &report.files {
        if let Some(name) = f.file_name() {
            text.push_str(&format!(" {}", name.to_string_lossy()));
        }
    }
    if !report.findings.is_empty() {
        text.push_str("\nworth a look (details in skeleton.json):");
        for f in &report.findings {
            text.push_str(&format!("\n  - {f}"));
        }
    }
    text
}

#[cfg(test)]
mod tests {
    use std::collections::BTreeMap;

    use super::*;
    use crate::tempdir::TempDir;

    /// A small synthetic capture written as C3D into `dir`.
    fn capture(dir: &Path) -> PathBuf {
        let config = synth::SynthConfig {
            subject: synth::Subject::Snowman,
            frames: 150,
            seed: 4242,
            ..synth::SynthConfig::default()
        };
        let trial = synth::generate(&config).unwrap();
        let path = dir.join("snowman.c3d");
        mocap_io::write_c3d(&path, &trial.trajectories).unwrap();
        path
    }

    /// A human and, 3 m along x, a snowman, moving each on its own in one capture written
    /// as C3D into `dir`, and each one's true segment count (the human has more).
    fn two_body_capture(dir: &Path) -> (PathBuf, [usize; 2]) {
        let trial = |subject, seed| {
            let config = synth::SynthConfig {
                subject,
                frames: 240,
                seed,
                ..synth::SynthConfig::default()
            };
            synth::generate(&config).unwrap()
        };
        let (a, b) = (
            trial(synth::Subject::Human, 31),
            trial(synth::Subject::Snowman, 32),
        );
        let (ta, tb) = (&a.trajectories, &b.trajectories);
        let mut labels = ta.labels().to_vec();
        labels.extend(tb.labels().iter().map(|l| format!("S{l}")));
        let mut positions = Vec::with_capacity(labels.len() * ta.frames());
        for f in 0..ta.frames() {
            positions.extend_from_slice(ta.frame(f));
            positions.extend(tb.frame(f).iter().map(|p| [p[0] + 3000.0, p[1], p[2]]));
        }
        let both = mocap_io::Trajectories::new(
            labels,
            ta.frame_rate(),
            ta.first_frame(),
            ta.frames(),
            positions,
        )
        .unwrap();
        let path = dir.join("two.c3d");
        mocap_io::write_c3d(&path, &both).unwrap();
        let segments = [a.truth.segments.len(), b.truth.segments.len()];
        (path, segments)
    }

    fn args(input: &Path, dir: &Path, set: &[&str]) -> Args {
        Args {
            input: vec![input.to_path_buf()],
            out: Some(dir.join("out")),
            set: set.iter().map(|s| s.to_string()).collect(),
            settings: None,
            from: None,
            force: false,
            json: false,
            cache: Some(dir.join("cache")),
        }
    }

    /// The default capture run once, quietly, into a fresh directory named `name`: the
    /// directory, the capture, the run's arguments and its report.
    fn first_run(name: &str) -> (TempDir, PathBuf, Args, Report) {
        let dir = TempDir::new(name).unwrap();
        let input = capture(dir.path());
        let a = args(&input, dir.path(), &[]);
        let first = execute(&a, &Progress::hidden()).unwrap();
        (dir, input, a, first)
    }

    /// skeleton.json as a run into `dir` wrote it.
    fn skeleton_json(dir: &TempDir) -> Vec<u8> {
        std::fs::read(dir.path().join("out/skeleton.json")).unwrap()
    }

    fn cached(report: &Report) -> Vec<bool> {
        report.stages.iter().map(|s| s.cached).collect()
    }

    #[test]
    fn reruns_reuse_exactly_what_did_not_change() {
        let (dir, input, a, first) = first_run("run");
        let quiet = Progress::hidden();
        assert_eq!(cached(&first), [false; 6]);
        let names: Vec<_> = first.stages.iter().map(|s| s.name).collect();
        assert_eq!(
            names,
            [
                "mocap-io", "segment", "jointfit", "topo", "bonefit", "export"
            ]
        );
        let json = skeleton_json(&dir);
        assert!(dir.path().join("out/skeleton.bvh").is_file());
        assert!(dir.path().join("cache/CACHEDIR.TAG").is_file());
        // export's entry, streamed file by file, is the artifact its files encode to, and
        // each file is the one written out.
        let cache = Cache::open(&dir.path().join("cache")).unwrap();
        let export_entry = cache.entry_path("export", export::SCHEMA_VERSION, &first.stages[5].key);
        let export_bytes = std::fs::read(&export_entry).unwrap();
        let (header, payload, hash) =
            pipeline::read_payload(StageId::Export, &export_entry).unwrap();
        assert_eq!(hash, first.stages[5].hash);
        let pipeline::Payload::Outputs(outputs) = payload else {
            panic!("export's entry holds another stage's payload")
        };
        assert_eq!(
            mocap_io::artifact::encode(&header, &outputs).unwrap(),
            export_bytes
        );
        assert_eq!(outputs.files.len(), first.files.len());
        for (name, bytes) in &outputs.files {
            assert_eq!(
                &std::fs::read(dir.path().join("out").join(name)).unwrap(),
                bytes
            );
        }

        // Nothing changed: every stage from the cache, same bytes out.
        let again = execute(&a, &quiet).unwrap();
        assert_eq!(cached(&again), [true; 6]);
        assert_eq!(skeleton_json(&dir), json);
        // ...and no stage's output decoded: entries read by header and hash, export's
        // files streamed out. A changed jointfit parameter decodes what jointfit reads.
        let run = |set: &[&str]| {
            let params = run_params(&args(&input, dir.path(), set)).unwrap();
            let out = dir.path().join("out");
            pipeline::run_cached(&input, &params, &cache, None, &quiet, &out).unwrap()
        };
        let (products, _, _) = run(&[]);
        assert!(products.capture.is_none() && products.segmentation.is_none());
        assert!(products.fits.is_none() && products.skeleton.is_none());
        let (products, _, _) = run(&["jointfit.alpha=0.3"]);
        assert!(products.capture.is_some() && products.segmentation.is_some());
        assert!(products.fits.is_some() && products.skeleton.is_some());

        // A jointfit parameter: jointfit and downstream rerun, upstream reused.
        let set = execute(&args(&input, dir.path(), &["jointfit.alpha=0.25"]), &quiet).unwrap();
        assert_eq!(cached(&set), [true, true, false, false, false, false]);
        // ...and going back to the default is all cache hits again.
        assert_eq!(cached(&execute(&a, &quiet).unwrap()), [true; 6]);

        // --from topo forces topo and downstream; --force everything.
        let from = Args {
            from: Some("topo".into()),
            ..args(&input, dir.path(), &[])
        };
        assert_eq!(
            cached(&execute(&from, &quiet).unwrap()),
            [true, true, true, false, false, false]
        );
        let force = Args {
            force: true,
            ..args(&input, dir.path(), &[])
        };
        assert_eq!(cached(&execute(&force, &quiet).unwrap()), [false; 6]);

        // A damaged entry is recomputed, not trusted and not a crash; a recomputed
        // artifact has the same bytes, so downstream stays cached.
        let seg = cache.entry_path("segment", segment::SCHEMA_VERSION, &first.stages[1].key);
        let bytes = std::fs::read(&seg).unwrap();
        std::fs::write(&seg, &bytes[..bytes.len() / 2]).unwrap();
        let repaired = execute(&a, &quiet).unwrap();
        assert_eq!(cached(&repaired), [true, false, true, true, true, true]);
        assert_eq!(std::fs::read(&seg).unwrap(), bytes);
        assert_eq!(skeleton_json(&dir), json);
        // A changed byte that still decodes is caught by the hash recorded at storing; an
        // entry with no record (an older ossify's) is recomputed too.
        let fits = cache.entry_path("jointfit", jointfit::SCHEMA_VERSION, &first.stages[2].key);
        let fits_bytes = std::fs::read(&fits).unwrap();
        let mut flipped = fits_bytes.clone();
        let last = flipped.len() - 1;
        flipped[last] ^= 1;
        std::fs::write(&fits, &flipped).unwrap();
        let repaired = execute(&a, &quiet).unwrap();
        assert_eq!(cached(&repaired), [true, true, false, true, true, true]);
        assert_eq!(std::fs::read(&fits).unwrap(), fits_bytes);
        std::fs::remove_file(fits.with_extension("blake3")).unwrap();
        let repaired = execute(&a, &quiet).unwrap();
        assert_eq!(cached(&repaired), [true, true, false, true, true, true]);
        assert_eq!(skeleton_json(&dir), json);
        // So is export's, read file by file into the output folder: a cut inside a file.
        std::fs::write(&export_entry, &export_bytes[..export_bytes.len() / 2]).unwrap();
        let repaired = execute(&a, &quiet).unwrap();
        assert_eq!(cached(&repaired), [true, true, true, true, true, false]);
        assert_eq!(std::fs::read(&export_entry).unwrap(), export_bytes);
        assert_eq!(skeleton_json(&dir), json);
    }

    /// A stage whose cache entry cannot be written still gives its artifact's hash, so the
    /// stages after it find their entries as before: the run is whole, only not cached.
    #[test]
    fn an_entry_that_cannot_be_written_leaves_the_run_whole() {
        let (dir, _, a, first) = first_run("run-unwritable");
        let json = skeleton_json(&dir);
        let cache = Cache::open(&dir.path().join("cache")).unwrap();
        let entry = cache.entry_path("jointfit", jointfit::SCHEMA_VERSION, &first.stages[2].key);
        std::fs::remove_file(&entry).unwrap();
        std::fs::create_dir(&entry).unwrap();
        let again = execute(&a, &Progress::hidden()).unwrap();
        assert_eq!(cached(&again), [true, true, false, true, true, true]);
        let hashes = |r: &Report| r.stages.iter().map(|s| s.hash.clone()).collect::<Vec<_>>();
        assert_eq!(hashes(&again), hashes(&first));
        assert!(entry.is_dir());
        assert_eq!(skeleton_json(&dir), json);
        // export's entry is written as its files are made: blocked, the files still come.
        let entry = cache.entry_path("export", export::SCHEMA_VERSION, &first.stages[5].key);
        std::fs::remove_file(&entry).unwrap();
        std::fs::create_dir(&entry).unwrap();
        std::fs::remove_file(dir.path().join("out/skeleton.json")).unwrap();
        let again = execute(&a, &Progress::hidden()).unwrap();
        assert_eq!(cached(&again), [true, true, false, true, true, false]);
        assert_eq!(hashes(&again), hashes(&first));
        assert_eq!(again.files, first.files);
        assert_eq!(skeleton_json(&dir), json);
    }

    /// The findings name what skeleton.json flags, and only that.
    #[test]
    fn findings_list_what_deserves_a_look() {
        let dir = TempDir::new("run-findings").unwrap();
        let input = capture(dir.path());
        let report = execute(&args(&input, dir.path(), &[]), &Progress::hidden()).unwrap();
        let bytes = std::fs::read(dir.path().join("out/skeleton.json")).unwrap();
        let mut doc: export::SkeletonJson = serde_json::from_slice(&bytes).unwrap();
        let clean = findings(&doc, 10.0);
        assert_eq!(report.findings, clean);
        assert!(
            clean.iter().all(|f| f.starts_with("joint ")),
            "a clean snowman flags only joints, if anything: {clean:?}"
        );
        doc.joints[0].warnings = vec!["range of motion 5.0° is below 20°".into()];
        for m in doc.markers.iter_mut().take(8) {
            m.segment = None;
            m.unassigned_reason = Some("visible in 3 of 150 frames".into());
        }
        doc.markers[9].slides = true;
        doc.markers[10].glitch_frames = 26;
        doc.markers[11].glitch_frames = 1;
        doc.detached_segments = vec![2];
        doc.notes = vec!["a rigid pair".into()];
        doc.segments[1].spin_deg = Some(14.2);
        doc.segments[2].spin_deg = Some(9.9);
        doc.segments[0].near_joint = Some(export::NearJointJson {
            parts: [vec!["M000".into()], vec!["M001".into(), "M002".into()]],
            rotation_z: 3.46,
            travel_z: 2.0,
        });
        doc.label_swaps = vec![export::LabelSwapJson {
            markers: ["M001".into(), "M007".into()],
            frames: vec![[10, 19], [40, 41]],
        }];
        let found = findings(&doc, 10.0);
        let nearly_in_line = found
            .iter()
            .find(|f| f.starts_with("segments whose markers nearly line up"))
            .unwrap_or_else(|| panic!("{found:?}"));
        let one = &doc.segments[1];
        assert!(
            nearly_in_line.ends_with(&format!("{} (±14°: {})", one.id, one.markers.join(", "))),
            "{nearly_in_line}"
        );
        assert!(
            findings(&doc, 0.0)
                .iter()
                .all(|f| !f.starts_with("segments whose"))
        );
        // Frames as the capture numbers them (first_frame on).
        let at = |i: i64| doc.first_frame + i;
        assert!(found.contains(&format!(
            "label swaps found and undone (trajectories exchanged; frames as in the capture): \
             1 — M001 ↔ M007 in frames {}–{}, {}–{}",
            at(10),
            at(19),
            at(40),
            at(41)
        )));
        let joint = &doc.joints[0];
        assert!(found.contains(&format!(
            "joint {} (segment {} → {}): range of motion 5.0° is below 20°",
            joint.name, joint.parent_segment, joint.child_segment
        )));
        let unassigned = found
            .iter()
            .find(|f| f.starts_with("markers in no segment: 8 — "))
            .unwrap_or_else(|| panic!("{found:?}"));
        assert!(
            unassigned.contains(": visible in 3 of 150 frames;")
                && unassigned.ends_with("and 2 more")
        );
        assert!(
            found.iter().any(|f| f.starts_with(
                "markers sliding against their segment (skin or a loose marker): 1 — "
            ) && f.contains(&doc.markers[9].label))
        );
        assert!(found.contains(&format!(
            "markers that left their partners in some frames (jumped off, or fell off and \
             lay still; those samples read as gaps): 2 — {} (26 frames); {} (1 frame)",
            doc.markers[10].label, doc.markers[11].label
        )));
        assert!(found.contains(&format!(
            "segments that may be two turning little about a joint (the joint test came near \
             cutting them where shown; skin can hide such a joint; where it is two, \
             --set 'segment.groups=[[\"LABEL\", ...]]' makes a part a segment): {} \
             (rotation z 3.5, travel z 2.0: M000 | M001, M002)",
            doc.segments[0].id
        )));
        assert!(found.contains(&"segments not in the tree: [2]".to_owned()));
        assert!(found.contains(&"topology: a rigid pair".to_owned()));
        let with_findings = Report {
            findings: found,
            ..report
        };
        assert!(summary(&with_findings).contains("worth a look"));
        // Another body's summary leaves out the stage table the first run printed.
        let stage_line = |text: &str| {
            text.lines()
                .any(|l| l.ends_with("cached") || l.ends_with("computed"))
        };
        assert!(stage_line(&summary(&with_findings)));
        let other = summary_with(&with_findings, false);
        assert!(
            !stage_line(&other) && other.contains("worth a look"),
            "{other}"
        );

        // As the smaller of two bodies, one segment none of the above is on: that
        // segment's findings, and nothing of the other body's or of the whole capture.
        let taken: Vec<Option<usize>> = (9..12)
            .map(|m| doc.markers[m].segment)
            .chain([Some(doc.segments[0].id), Some(2)])
            .collect();
        let own = doc
            .segments
            .iter()
            .map(|s| s.id)
            .find(|&id| !taken.contains(&Some(id)))
            .unwrap();
        doc.segments
            .iter_mut()
            .find(|s| s.id == own)
            .unwrap()
            .spin_deg = Some(15.0);
        let others = doc.segments.iter().map(|s| s.id).filter(|&id| id != own);
        doc.bodies = vec![
            export::BodyJson {
                name: "body1".into(),
                segments: others.collect(),
                marker_count: 40,
            },
            export::BodyJson {
                name: "body2".into(),
                segments: vec![own],
                marker_count: 3,
            },
        ];
        doc.body = Some("body2".into());
        doc.detached_segments = doc.bodies[0].segments.clone();
        let second = findings(&doc, 10.0);
        let in_line = second
            .iter()
            .find(|f| f.starts_with("segments whose markers nearly line up"))
            .unwrap_or_else(|| panic!("{second:?}"));
        assert!(in_line.contains(&format!("{own} (±15°")) && !in_line.contains("±14°"));
        assert!(
            second
                .iter()
                .any(|f| f.starts_with("another body, body1: "))
        );
        // Beside many bodies, one line names them all.
        let mut many = doc.clone();
        for k in 3..=5 {
            many.bodies.push(export::BodyJson {
                name: format!("body{k}"),
                segments: Vec::new(),
                marker_count: 4,
            });
        }
        let listed = findings(&many, 10.0);
        assert!(
            !listed.iter().any(|f| f.starts_with("another body")),
            "{listed:?}"
        );
        assert!(
            listed.iter().any(|f| f.starts_with(
                "4 other bodies, each a skeleton of its own (no pair between it and this \
                 tree fits a joint): body1 (",
            ) && f.ends_with("; body5 (0 segments, 4 markers)")),
            "{listed:?}"
        );
        for gone in [
            "markers in no segment",
            "label swaps",
            "markers sliding",
            "markers that left their partners",
            "segments that may be two",
            "segments not in the tree",
        ] {
            assert!(
                !second.iter().any(|f| f.starts_with(gone)),
                "{gone}: {second:?}"
            );
        }
    }

    #[test]
    fn each_body_of_a_capture_gets_its_own_files() {
        let dir = TempDir::new("run-bodies").unwrap();
        let (input, true_segments) = two_body_capture(dir.path());
        assert!(true_segments[0] > true_segments[1]);
        let report = execute(&args(&input, dir.path(), &[]), &Progress::hidden()).unwrap();
        let read = |path: PathBuf| -> export::SkeletonJson {
            serde_json::from_slice(&std::fs::read(path).unwrap()).unwrap()
        };
        let first = read(dir.path().join("out/skeleton.json"));
        let second = read(dir.path().join("out/body2/skeleton.json"));
        assert_eq!(report.other_bodies.len(), 1);
        assert_eq!(report.other_bodies[0].out, dir.path().join("out/body2"));
        // Each body's summary counts its own segments.
        assert_eq!(report.segments, true_segments[0]);
        assert_eq!(report.other_bodies[0].segments, true_segments[1]);
        for (r, other) in [(&report, "body2"), (&report.other_bodies[0], "body1")] {
            let said = format!("another body, {other}: ");
            assert!(
                r.findings.iter().any(|f| f.starts_with(&said)),
                "{:?}",
                r.findings
            );
            assert!(
                !r.findings
                    .iter()
                    .any(|f| f.starts_with("segments not in the tree"))
            );
        }
        let page = std::fs::read_to_string(dir.path().join("out/report.html")).unwrap();
        assert!(page.contains("The capture holds 2 bodies, no joint between them: this is body1"));
        assert_eq!(first.bodies, second.bodies);
        let names: Vec<&str> = first.bodies.iter().map(|b| b.name.as_str()).collect();
        assert_eq!(names, ["body1", "body2"]);
        for (k, doc) in [&first, &second].into_iter().enumerate() {
            assert_eq!(doc.body.as_deref(), Some(names[k]));
            let body = &doc.bodies[k].segments;
            assert_eq!(body.len(), true_segments[k]);
            assert_eq!(doc.joints.len(), true_segments[k] - 1);
            assert!(body.contains(&doc.root_segment));
            for j in &doc.joints {
                assert!(body.contains(&j.parent_segment) && body.contains(&j.child_segment));
            }
            // Each body's markers are its own subject's: the snowman's were renamed S….
            let markers = doc.segments.iter().filter(|s| body.contains(&s.id));
            let snowman = markers.flat_map(|s| &s.markers).all(|m| m.starts_with('S'));
            assert_eq!(snowman, k == 1);
        }
    }

    #[test]
    fn a_skeleton_json_or_a_settings_object_gives_the_run_its_parameters() {
        let dir = TempDir::new("run-settings").unwrap();
        let input = capture(dir.path());
        let first = args(
            &input,
            dir.path(),
            &["topo.root=0", "jointfit.min_frames=40"],
        );
        execute(&first, &Progress::hidden()).unwrap();
        let made = dir.path().join("out/skeleton.json");
        let doc: serde_json::Value =
            serde_json::from_slice(&std::fs::read(&made).unwrap()).unwrap();
        assert_eq!(
            doc["settings"],
            json!({"topo.root": 0, "jointfit.min_frames": 40})
        );
        // Rerun as that file was made, a --set on top; or from a plain settings object.
        let again_dir = dir.path().join("again");
        let mut again = args(&input, &again_dir, &["bonefit.method=paper"]);
        again.settings = Some(made.clone());
        assert_eq!(
            run_params(&again).unwrap().changed().unwrap(),
            BTreeMap::from([
                ("bonefit.method".to_string(), json!("paper")),
                ("jointfit.min_frames".to_string(), json!(40)),
                ("topo.root".to_string(), json!(0)),
            ])
        );
        let object = dir.path().join("settings.json");
        std::fs::write(&object, r#"{"segment.groups": [["M000", "M001"]]}"#).unwrap();
        again.settings = Some(object.clone());
        again.set.clear();
        let changed = run_params(&again).unwrap().changed().unwrap();
        assert_eq!(changed["segment.groups"], json!([["M000", "M001"]]));
        // What cannot be read says which file and why.
        for (text, says) in [
            ("not json", "not JSON"),
            ("[1, 2]", "expected a JSON object"),
            (r#"{"segment.no_such": 1}"#, "segment.no_such"),
        ] {
            std::fs::write(&object, text).unwrap();
            let e = format!("{:#}", run_params(&again).unwrap_err());
            assert!(e.contains("settings.json") && e.contains(says), "{e}");
        }
    }

    #[test]
    fn a_named_group_that_is_not_one_body_is_worth_a_look() {
        let dir = TempDir::new("run-named-loose").unwrap();
        let input = capture(dir.path());
        execute(&args(&input, dir.path(), &[]), &Progress::hidden()).unwrap();
        let bytes = std::fs::read(dir.path().join("out/skeleton.json")).unwrap();
        let mut doc: export::SkeletonJson = serde_json::from_slice(&bytes).unwrap();
        let flagged = |doc: &export::SkeletonJson| {
            findings(doc, 10.0)
                .into_iter()
                .find(|f| f.starts_with("segments segment.groups named"))
        };
        // Named and as rigid as the rest (2 mm, skin's): nothing to say.
        for m in &mut doc.markers {
            m.rigidity_residual_mm = Some(2.0);
        }
        doc.segments[1].named = true;
        assert_eq!(flagged(&doc), None);
        // Its markers ten times as loose as the rest's (a group across a joint).
        let loose = doc.segments[1].markers.clone();
        for m in doc.markers.iter_mut().filter(|m| loose.contains(&m.label)) {
            m.rigidity_residual_mm = Some(20.0);
        }
        let said = flagged(&doc).unwrap_or_else(|| panic!("{:?}", findings(&doc, 10.0)));
        assert!(
            said.ends_with(&format!(
                ": {} (20.0 mm median rigidity residual, 10.0 times the median segment's 2.0 mm)",
                doc.segments[1].id
            )),
            "{said}"
        );
        // The same looseness on a segment the data made is not the user's to check.
        doc.segments[1].named = false;
        assert_eq!(flagged(&doc), None);
    }

    #[test]
    fn bad_input_or_parameter_fails_naming_it_and_writes_nothing() {
        let dir = TempDir::new("run-bad").unwrap();
        let bad = dir.path().join("broken.c3d");
        std::fs::write(&bad, b"not a c3d file at all").unwrap();
        let err = execute(&args(&bad, dir.path(), &[]), &Progress::hidden()).unwrap_err();
        let text = format!("{err:#}");
        assert!(
            text.contains("broken.c3d") && text.contains("mocap-io"),
            "{text}"
        );
        assert!(!dir.path().join("out").exists());

        let input = capture(dir.path());
        let err = execute(
            &args(&input, dir.path(), &["jointfit.nope=1"]),
            &Progress::hidden(),
        )
        .unwrap_err();
        assert!(format!("{err:#}").contains("alpha"), "{err:#}");
        assert!(!dir.path().join("out").exists());
    }

    /// Runs every stage alone with `stage`, each on the artifacts the one before wrote,
    /// and checks each artifact against the one `run` cached for `report`.
    fn stage_by_stage_matches_the_cache(
        input: &Path,
        dir: &Path,
        report: &Report,
        settings: Option<&Path>,
        set: impl Fn(StageId) -> Vec<String>,
    ) {
        let cache = Cache::open(&dir.join("cache")).unwrap();
        let mut previous: Vec<PathBuf> = Vec::new();
        for (stage, run) in StageId::ALL.iter().zip(&report.stages) {
            let out = dir.join(format!("{}.cbor", stage.name()));
            let inputs = if *stage == StageId::MocapIo {
                vec![input.to_path_buf()]
            } else {
                stage
                    .inputs()
                    .iter()
                    .map(|s| previous[*s as usize].clone())
                    .collect()
            };
            crate::stage_cmd::execute(&crate::stage_cmd::Args {
                name: stage.name().into(),
                inputs,
                out: out.clone(),
                settings: settings.map(Path::to_path_buf),
                set: set(*stage),
            })
            .unwrap();
            let cached = cache.entry_path(stage.name(), stage.schema_version(), &run.key);
            assert_eq!(
                std::fs::read(&out).unwrap(),
                std::fs::read(&cached).unwrap(),
                "{} differs from the cache",
                stage.name()
            );
            previous.push(out);
        }
    }

    #[test]
    fn stage_command_writes_the_same_artifacts_as_run() {
        let dir = TempDir::new("stage").unwrap();
        let input = capture(dir.path());
        // An upstream setting, which export records in skeleton.json as run does.
        let set = "topo.root=0";
        let report = execute(&args(&input, dir.path(), &[set]), &Progress::hidden()).unwrap();
        stage_by_stage_matches_the_cache(&input, dir.path(), &report, None, |stage| {
            if stage == StageId::Topo {
                vec![set.into()]
            } else {
                Vec::new()
            }
        });
    }

    #[test]
    fn stage_command_takes_a_runs_settings_file() {
        let dir = TempDir::new("stage-settings").unwrap();
        let input = capture(dir.path());
        let set = ["jointfit.min_frames=40", "topo.root=0"];
        let report = execute(&args(&input, dir.path(), &set), &Progress::hidden()).unwrap();
        let made = dir.path().join("out/skeleton.json");
        // Every stage takes its own entries of the skeleton.json the run wrote.
        stage_by_stage_matches_the_cache(&input, dir.path(), &report, Some(&made), |_| Vec::new());
        // Inputs made with other upstream settings than the file gives are refused, naming
        // the artifact and the parameter; nothing is written.
        let object = dir.path().join("settings.json");
        std::fs::write(&object, r#"{"jointfit.min_frames": 50}"#).unwrap();
        let out = dir.path().join("refused-topo.cbor");
        let err = crate::stage_cmd::execute(&crate::stage_cmd::Args {
            name: "topo".into(),
            inputs: vec![
                dir.path().join("segment.cbor"),
                dir.path().join("jointfit.cbor"),
            ],
            out: out.clone(),
            settings: Some(object),
            set: Vec::new(),
        })
        .unwrap_err();
        let text = format!("{err:#}");
        assert!(
            text.contains("jointfit.cbor")
                && text.contains("jointfit.min_frames 50 in the file, 40 in the artifact"),
            "{text}"
        );
        assert!(!out.exists());
    }
}
