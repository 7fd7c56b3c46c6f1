//! The content-addressed artifact cache.
//!
//! Layout (everything below one root, by default `<project root>/.cache/ossify/`, or
//! `$OSSIFY_CACHE`, or `--cache DIR`):
//!
//! ```text
//! <cache>/CACHEDIR.TAG                      marks the folder as a cache for backup tools
//! <cache>/<stage>-v<schema>/<key>.cbor      one artifact per stage run
//! <cache>/<stage>-v<schema>/<key>.blake3    its content hash as it was stored
//! ```
//!
//! `<key>` is the hex blake3 of the stage name, its schema version, the canonical CBOR of
//! its parameters (maps sorted by encoded key, so field or map order never matters) and
//! the content hashes of its input artifacts (for mocap-io: the capture file's bytes).
//! Same key → the artifact is reused; anything changed → a new key, so the stage and,
//! through the changed artifact hash, everything downstream rerun, nothing upstream.
//!
//! Entries are written atomically (temporary file + rename). An entry is never trusted
//! blindly: the runner checks its header against the key's ingredients and its content
//! hash against the one recorded when it was stored, and recomputes (with a warning) when
//! either fails, or (silently) when no hash was recorded; it decodes the payload only
//! where a stage to compute reads it, and recomputes one that fails to decode then.
//! Bumping a stage's schema version starts a new bucket; `cargo xtask cache prune` drops
//! buckets no stage uses any more.

use std::path::{Path, PathBuf};

use anyhow::{Context as _, Result};
use mocap_io::artifact::{InputHash, write_atomic};
use serde::Serialize;

/// Environment variable naming the cache folder.
pub const ENV_VAR: &str = "OSSIFY_CACHE";

const CACHEDIR_TAG: &str = "Signature: 8a477f597d28d172789f06886806bc55\n\
# This file is a cache directory tag created by ossify (cargo xtask).\n\
# For information about cache directory tags see https://bford.info/cachedir/\n";

/// `cargo xtask cache ...`.
#[derive(clap::Subcommand)]
pub enum Command {
    /// Drop buckets of unknown stages or old schema versions (or everything with --all).
    Prune {
        /// Cache folder (default: $OSSIFY_CACHE, else <project root>/.cache/ossify).
        #[arg(long, value_name = "DIR")]
        cache: Option<PathBuf>,
        /// Remove every entry, not only stale buckets.
        #[arg(long)]
        all: bool,
    },
    /// Print the cache folder and the size of each bucket.
    Info {
        /// Cache folder (default: $OSSIFY_CACHE, else <project root>/.cache/ossify).
        #[arg(long, value_name = "DIR")]
        cache: Option<PathBuf>,
    },
}

/// Runs `cache ...`.
pub fn main(command: &Command) -> Result<()> {
    match command {
        Command::Prune { cache, all } => {
            let cache = Cache::open(&resolve_root(cache.as_deref()))?;
            let known = crate::pipeline::buckets();
            let removed = cache.prune(&known, *all)?;
            for r in &removed {
                println!("removed {}", r.display());
            }
            println!(
                "{} bucket(s) removed from {}",
                removed.len(),
                cache.root().display()
            );
            Ok(())
        }
        Command::Info { cache } => {
            let root = resolve_root(cache.as_deref());
            println!("cache {}", root.display());
            if !root.is_dir() {
                println!("(empty)");
                return Ok(());
            }
            let mut buckets: Vec<_> = std::fs::read_dir(&root)
                .with_context(|| format!("{}: cannot list", root.display()))?
                .filter_map(|e| e.ok())
                .filter(|e| e.path().is_dir())
                .collect();
            buckets.sort_by_key(|e| e.file_name());
            for b in buckets {
                let (n, bytes) = std::fs::read_dir(b.path())
                    .map(|rd| {
                        rd.filter_map(|e| e.ok())
                            .filter_map(|e| e.metadata().ok())
                            .fold((0usize, 0u64), |(n, s), m| (n + 1, s + m.len()))
                    })
                    .unwrap_or((0, 0));
                println!(
                    "  {:<16} {n:>5} entries {:>10.1} MB",
                    b.file_name().to_string_lossy(),
                    bytes as f64 / 1e6
                );
            }
            Ok(())
        }
    }
}

/// The cache root: `--cache`, else `$OSSIFY_CACHE`, else `<project root>/.cache/ossify`.
pub fn resolve_root(flag: Option<&Path>) -> PathBuf {
    if let Some(dir) = flag {
        return dir.to_path_buf();
    }
    match std::env::var_os(ENV_VAR) {
        Some(v) if !v.is_empty() => PathBuf::from(v),
        _ => crate::project_root().join(".cache").join("ossify"),
    }
}

/// An opened cache folder.
#[derive(Clone, Debug)]
pub struct Cache {
    root: PathBuf,
}

impl Cache {
    /// Opens (creating if needed) a cache folder and its `CACHEDIR.TAG`.
    pub fn open(root: &Path) -> Result<Self> {
        std::fs::create_dir_all(root)
            .with_context(|| format!("{}: cannot create the cache folder", root.display()))?;
        let tag = root.join("CACHEDIR.TAG");
        if !tag.is_file() {
            write_atomic(&tag, CACHEDIR_TAG.as_bytes())?;
        }
        Ok(Self {
            root: root.to_path_buf(),
        })
    }

    /// The cache folder.
    pub fn root(&self) -> &Path {
        &self.root
    }

    /// Folder name of a stage's bucket: `<stage>-v<schema>`.
    pub fn bucket_name(stage: &str, schema_version: u32) -> String {
        format!("{stage}-v{schema_version}")
    }

    /// Path of the entry for a key.
    pub fn entry_path(&self, stage: &str, schema_version: u32, key: &str) -> PathBuf {
        self.root
            .join(Self::bucket_name(stage, schema_version))
            .join(format!("{key}.cbor"))
    }

    /// Records an entry's content hash as stored (`<key>.blake3` beside `<key>.cbor`), so
    /// a later run can tell an entry changed on disk from the one written.
    pub fn record_hash(entry: &Path, hash: &str) -> Result<()> {
        Ok(write_atomic(
            &entry.with_extension("blake3"),
            hash.as_bytes(),
        )?)
    }

    /// The content hash recorded when `entry` was stored; `None` where none was (an
    /// entry of an older ossify, or its record could not be written).
    pub fn recorded_hash(entry: &Path) -> Option<String> {
        let text = std::fs::read_to_string(entry.with_extension("blake3")).ok()?;
        Some(text.trim().to_owned())
    }

    /// Removes buckets not in `known` (`<stage>-v<schema>` names), or every bucket with
    /// `all`; returns what was removed. Files at the top level other than the tag go too.
    pub fn prune(&self, known: &[String], all: bool) -> Result<Vec<PathBuf>> {
        let mut removed = Vec::new();
        let entries = std::fs::read_dir(&self.root)
            .with_context(|| format!("{}: cannot list", self.root.display()))?;
        for entry in entries {
            let entry = entry.with_context(|| format!("{}: cannot list", self.root.display()))?;
            let name = entry.file_name().to_string_lossy().into_owned();
            let path = entry.path();
            if name == "CACHEDIR.TAG" {
                continue;
            }
            let keep = !all && path.is_dir() && known.contains(&name);
            if keep {
                continue;
            }
            if path.is_dir() {
                std::fs::remove_dir_all(&path)
            } else {
                std::fs::remove_file(&path)
            }
            .with_context(|| format!("{}: cannot remove", path.display()))?;
            removed.push(path);
        }
        removed.sort();
        Ok(removed)
    }
}

/// A value as canonical CBOR: serialized, then every map sorted by its keys' encoded bytes.
///
/// Struct fields, `BTreeMap`s and even `HashMap`s all end up in one order, so equal
/// parameters always give equal bytes and equal cache keys.
pub fn canonical_value<T: Serialize + ?Sized>(value: &T) -> Result<ciborium::Value> {
    let mut v = ciborium::Value::serialized(value).context("cannot encode parameters as CBOR")?;
    canonicalize(&mut v);
    Ok(v)
}

fn canonicalize(v: &mut ciborium::Value) {
    use ciborium::Value as V;
    match v {
        V::Map(entries) => {
            for (k, x) in entries.iter_mut() {
                canonicalize(k);
                canonicalize(x);
            }
            // RFC 8949 §4.2.1: sort by the bytewise order of the encoded keys.
            entries.sort_by_cached_key(|(k, _)| encode(k));
        }
        V::Array(items) => items.iter_mut().for_each(canonicalize),
        V::Tag(_, inner) => canonicalize(inner),
        _ => {}
    }
}

/// Encodes a CBOR value (canonical when the value is).
pub fn encode(v: &ciborium::Value) -> Vec<u8> {
    let mut out = Vec::new();
    // Writing a Value into a Vec cannot fail: no I/O, no foreign Serialize impl.
    if ciborium::into_writer(v, &mut out).is_err() {
        out.clear();
    }
    out
}

/// The cache key of a stage run, hex blake3.
///
/// Every ingredient is length-prefixed, so no two different ingredient lists hash alike
/// by concatenation.
pub fn cache_key(
    stage: &str,
    schema_version: u32,
    canonical_params: &[u8],
    inputs: &[InputHash],
) -> String {
    let mut h = blake3::Hasher::new();
    let mut field = |bytes: &[u8]| {
        h.update(&(bytes.len() as u64).to_le_bytes());
        h.update(bytes);
    };
    field(b"ossify cache key v1");
    field(stage.as_bytes());
    field(&schema_version.to_le_bytes());
    field(canonical_params);
    field(&(inputs.len() as u64).to_le_bytes());
    for input in inputs {
        field(input.role.as_bytes());
        field(input.blake3.as_bytes());
    }
    h.finalize().to_hex().to_string()
}

#[cfg(test)]
mod tests {
    use std::collections::{BTreeMap, HashMap};

    use super::*;
    use crate::tempdir::TempDir;

    #[derive(Serialize)]
    struct P {
        alpha: f64,
        method: String,
        extra: HashMap<String, u32>,
    }

    fn inputs() -> Vec<InputHash> {
        vec![InputHash {
            role: "mocap-io".into(),
            blake3: mocap_io::artifact::content_hash(b"capture"),
        }]
    }

    fn key_of<T: Serialize>(p: &T, inputs: &[InputHash]) -> String {
        let bytes = encode(&canonical_value(p).unwrap());
        cache_key("jointfit", 1, &bytes, inputs)
    }

    #[test]
    fn same_params_same_key_changed_param_different_key() {
        let p = |alpha| P {
            alpha,
            method: "aguiar".into(),
            extra: HashMap::new(),
        };
        assert_eq!(key_of(&p(0.2), &inputs()), key_of(&p(0.2), &inputs()));
        assert_ne!(key_of(&p(0.2), &inputs()), key_of(&p(0.25), &inputs()));
        let mut other = inputs();
        other[0].blake3 = mocap_io::artifact::content_hash(b"another capture");
        assert_ne!(key_of(&p(0.2), &inputs()), key_of(&p(0.2), &other));
        // Stage name and schema version are ingredients too.
        let bytes = encode(&canonical_value(&p(0.2)).unwrap());
        assert_ne!(
            cache_key("jointfit", 1, &bytes, &inputs()),
            cache_key("jointfit", 2, &bytes, &inputs())
        );
        assert_ne!(
            cache_key("jointfit", 1, &bytes, &inputs()),
            cache_key("topo", 1, &bytes, &inputs())
        );
    }

    #[test]
    fn key_does_not_depend_on_map_order() {
        // HashMaps built in different insertion orders (and with different hash seeds)
        // iterate differently; the canonical encoding must not care.
        let names: Vec<String> = (0..40).map(|i| format!("k{i}")).collect();
        let mut forward = HashMap::new();
        for (i, n) in names.iter().enumerate() {
            forward.insert(n.clone(), i as u32);
        }
        let mut backward = HashMap::new();
        for (i, n) in names.iter().enumerate().rev() {
            backward.insert(n.clone(), i as u32);
        }
        let a = P {
            alpha: 0.2,
            method: "score".into(),
            extra: forward,
        };
        let b = P {
            alpha: 0.2,
            method: "score".into(),
            extra: backward,
        };
        assert_eq!(key_of(&a, &inputs()), key_of(&b, &inputs()));
        // A BTreeMap with the same content gives the same canonical bytes as a HashMap.
        let sorted: BTreeMap<_, _> = a.extra.iter().map(|(k, v)| (k.clone(), *v)).collect();
        assert_eq!(
            encode(&canonical_value(&sorted).unwrap()),
            encode(&canonical_value(&a.extra).unwrap())
        );
    }

    #[test]
    fn key_is_stable_across_versions_of_this_code() {
        // Pinned so an accidental change of the key recipe (which would silently orphan
        // every cache entry) shows up as a failing test.
        let bytes = encode(&canonical_value(&BTreeMap::from([("alpha", 0.5)])).unwrap());
        let k = cache_key("jointfit", 1, &bytes, &[]);
        assert_eq!(k.len(), 64);
        assert_eq!(k, cache_key("jointfit", 1, &bytes, &[]));
        assert_eq!(
            k, PINNED_KEY,
            "cache key recipe changed: bump the recipe tag"
        );
    }
    const PINNED_KEY: &str = "077edfe968b2e481d5bb252b5df4f8ee775a54bedde17570a596c4a0683dc75a";

    #[test]
    fn entries_live_in_their_bucket_and_prune_drops_stale_buckets() {
        let dir = TempDir::new("cache").unwrap();
        let cache = Cache::open(dir.path()).unwrap();
        assert!(dir.path().join("CACHEDIR.TAG").is_file());
        let entry = cache.entry_path("segment", 1, "abc");
        assert_eq!(entry, dir.path().join("segment-v1").join("abc.cbor"));
        write_atomic(&entry, b"hello").unwrap();
        write_atomic(&cache.entry_path("segment", 0, "old"), b"x").unwrap();
        let removed = cache.prune(&["segment-v1".into()], false).unwrap();
        assert_eq!(removed, vec![dir.path().join("segment-v0")]);
        assert_eq!(std::fs::read(&entry).unwrap(), b"hello");
        cache.prune(&["segment-v1".into()], true).unwrap();
        assert!(!entry.exists());
        assert!(dir.path().join("CACHEDIR.TAG").is_file());
    }
}
