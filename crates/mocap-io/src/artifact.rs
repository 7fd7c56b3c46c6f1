//! The CBOR envelope every stage artifact is stored in, and content hashing.
//!
//! File layout: the CBOR self-describe tag 55799 (bytes `d9 d9 f7`, our magic) around a
//! map `{ "header": ArtifactHeader, "payload": <stage payload> }`. Bulk floats in a
//! payload are byte strings (see [`crate::bulk`]). Maps are `BTreeMap`s or structs, never
//! `HashMap`s, so the same value always encodes to the same bytes. Files are written and
//! read as they stream ([`write_hashed`], [`read_hashed`]), their content hash taken on the
//! way, so an artifact of hundreds of megabytes is never whole in memory beside its value.

use std::io::{BufReader, BufWriter, Read, Write};
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicU64, Ordering};

use serde::{Deserialize, Serialize, de::DeserializeOwned};

use crate::error::IoError;

mod byte_map;
pub use byte_map::{ByteMapReader, ByteMapWriter, read_header_hashed};

/// The CBOR self-describe tag that opens every artifact.
pub const MAGIC: [u8; 3] = [0xd9, 0xd9, 0xf7];
const SELF_DESCRIBE_TAG: u64 = 55799;

/// What an artifact is, what made it and what it came from.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct ArtifactHeader {
    /// Stage that produced the payload: "mocap-io", "segment", "jointfit", ...
    pub stage: String,
    /// Version of the stage's payload schema and algorithm; bumped when either changes.
    pub schema_version: u32,
    /// Version of ossify that wrote the file.
    pub tool_version: String,
    /// The stage's parameters, as the stage's serde struct encodes them.
    pub params: ciborium::Value,
    /// Content hashes of the inputs, by role ("capture", "segment", ...).
    pub inputs: Vec<InputHash>,
}

/// One input of an artifact: its role and the blake3 hash of its bytes.
#[derive(Clone, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub struct InputHash {
    /// Role of the input for the stage ("capture", "segment", ...).
    pub role: String,
    /// Lower-case hex blake3 of the input file's bytes.
    pub blake3: String,
}

#[derive(Serialize, Deserialize)]
struct Envelope<H, P> {
    header: H,
    payload: P,
}

/// Lower-case hex blake3 hash of some bytes.
pub fn content_hash(bytes: &[u8]) -> String {
    blake3::hash(bytes).to_hex().to_string()
}

/// Encodes a header and payload as artifact bytes.
pub fn encode<P: Serialize>(header: &ArtifactHeader, payload: &P) -> Result<Vec<u8>, IoError> {
    let mut out = Vec::new();
    encode_into(header, payload, &mut out).map_err(|e| IoError::Invalid(e.to_string()))?;
    Ok(out)
}

/// Encodes a header and payload into `out`; an encoding failure is an `io::Error` too.
fn encode_into<P: Serialize>(
    header: &ArtifactHeader,
    payload: &P,
    out: impl Write,
) -> std::io::Result<()> {
    let env = ciborium::tag::Required::<_, SELF_DESCRIBE_TAG>(Envelope { header, payload });
    ciborium::into_writer(&env, out).map_err(|e| match e {
        ciborium::ser::Error::Io(e) => e,
        ciborium::ser::Error::Value(v) => {
            std::io::Error::other(format!("cannot encode artifact: {v}"))
        }
    })
}

/// Bytes passing through, hashed on the way (blake3), so an artifact's [`content_hash`]
/// comes without holding its bytes: a payload can be hundreds of megabytes.
#[derive(Debug)]
struct Hashing<T> {
    inner: T,
    hasher: blake3::Hasher,
}

impl<T> Hashing<T> {
    fn new(inner: T) -> Self {
        Self {
            inner,
            hasher: blake3::Hasher::new(),
        }
    }

    fn hash(&self) -> String {
        self.hasher.finalize().to_hex().to_string()
    }
}

impl<W: Write> Write for Hashing<W> {
    fn write(&mut self, buf: &[u8]) -> std::io::Result<usize> {
        let n = self.inner.write(buf)?;
        self.hasher.update(&buf[..n]);
        Ok(n)
    }

    fn flush(&mut self) -> std::io::Result<()> {
        self.inner.flush()
    }
}

impl<R: Read> Read for Hashing<R> {
    fn read(&mut self, buf: &mut [u8]) -> std::io::Result<usize> {
        let n = self.inner.read(buf)?;
        self.hasher.update(&buf[..n]);
        Ok(n)
    }
}

/// The [`content_hash`] of the bytes [`encode`] gives, without making them.
pub fn encoded_hash<P: Serialize>(header: &ArtifactHeader, payload: &P) -> Result<String, IoError> {
    let mut sink = Hashing::new(std::io::sink());
    encode_into(header, payload, &mut sink).map_err(|e| IoError::Invalid(e.to_string()))?;
    Ok(sink.hash())
}

/// Encodes and writes an artifact atomically, streamed to the file rather than built in
/// memory first; returns the [`content_hash`] of the bytes written.
pub fn write_hashed<P: Serialize>(
    path: &Path,
    header: &ArtifactHeader,
    payload: &P,
) -> Result<String, IoError> {
    let mut hash = String::new();
    let tmp = write_temp_with(path, |file| {
        let mut out = Hashing::new(BufWriter::with_capacity(STREAM_BUFFER, file));
        encode_into(header, payload, &mut out)?;
        out.flush()?;
        hash = out.hash();
        Ok(())
    })?;
    rename_into(&tmp, path)?;
    Ok(hash)
}

/// Reads and decodes an artifact file as it streams in, never holding its bytes; returns
/// the header, the payload and the [`content_hash`] of the whole file. Errors as [`read`]'s
/// but for the stage, which the caller checks.
pub fn read_hashed<P: DeserializeOwned>(
    path: &Path,
) -> Result<(ArtifactHeader, P, String), IoError> {
    let bad = |problem: String| IoError::Artifact {
        path: path.to_path_buf(),
        problem,
    };
    let file = std::fs::File::open(path).map_err(|source| IoError::Read {
        path: path.to_path_buf(),
        source,
    })?;
    let mut input = Hashing::new(BufReader::with_capacity(STREAM_BUFFER, file));
    let mut head = [0u8; MAGIC.len()];
    let opened = read_up_to(&mut input, &mut head).map_err(|e| bad(e.to_string()))?;
    if head[..opened] != MAGIC {
        return Err(bad(
            "missing the CBOR self-describe tag (d9 d9 f7) that opens every artifact".into(),
        ));
    }
    let mut envelope = (&head[..]).chain(&mut input);
    let env: ciborium::tag::Required<Envelope<ArtifactHeader, P>, SELF_DESCRIBE_TAG> =
        ciborium::from_reader(&mut envelope).map_err(|e| bad(cbor_problem(&e, 0, io_problem)))?;
    // Bytes after the envelope are hashed too: the hash is the file's.
    std::io::copy(&mut input, &mut std::io::sink()).map_err(|e| bad(e.to_string()))?;
    Ok((env.0.header, env.0.payload, input.hash()))
}

/// A decoding failure in a user's words: where the bytes stop making sense (counted from
/// the file's start: `base` is where the decoding began), or that the file ends early.
/// `read_failure` words a failed read, `None` where it was the end of the input.
fn cbor_problem<T>(
    e: &ciborium::de::Error<T>,
    base: usize,
    read_failure: impl Fn(&T) -> Option<String>,
) -> String {
    use ciborium::de::Error as E;
    match e {
        E::Io(io) => read_failure(io)
            .unwrap_or_else(|| "the file ends inside the artifact (cut short?)".to_owned()),
        E::Syntax(at) => format!("not valid CBOR at byte {}", base + at),
        E::Semantic(Some(at), what) => format!("byte {}: {what}", base + at),
        E::Semantic(None, what) => what.clone(),
        E::RecursionLimitExceeded => "nested too deeply to be an artifact".to_owned(),
    }
}

/// A failed read as [`cbor_problem`] words it.
fn io_problem(e: &std::io::Error) -> Option<String> {
    (e.kind() != std::io::ErrorKind::UnexpectedEof).then(|| format!("cannot read: {e}"))
}

/// Reads into `buf` until it is full or the input ends; returns how much was read.
fn read_up_to(input: &mut impl Read, buf: &mut [u8]) -> std::io::Result<usize> {
    let mut filled = 0;
    while filled < buf.len() {
        match input.read(&mut buf[filled..]) {
            Ok(0) => break,
            Ok(n) => filled += n,
            Err(e) if e.kind() == std::io::ErrorKind::Interrupted => {}
            Err(e) => return Err(e),
        }
    }
    Ok(filled)
}

/// Buffer of a streamed artifact read or write.
const STREAM_BUFFER: usize = 1 << 16;

/// Decodes artifact bytes into header and payload; `path` only names the source in errors.
pub fn decode<P: DeserializeOwned>(
    bytes: &[u8],
    path: &Path,
) -> Result<(ArtifactHeader, P), IoError> {
    let bad = |problem: String| IoError::Artifact {
        path: path.to_path_buf(),
        problem,
    };
    if !bytes.starts_with(&MAGIC) {
        return Err(bad(
            "missing the CBOR self-describe tag (d9 d9 f7) that opens every artifact".into(),
        ));
    }
    let env: ciborium::tag::Required<Envelope<ArtifactHeader, P>, SELF_DESCRIBE_TAG> =
        ciborium::from_reader(bytes).map_err(|e| bad(cbor_problem(&e, 0, |_| None)))?;
    Ok((env.0.header, env.0.payload))
}

/// Reads and decodes an artifact file, checking that it came from `stage`.
pub fn read<P: DeserializeOwned>(path: &Path, stage: &str) -> Result<(ArtifactHeader, P), IoError> {
    let (header, payload, _) = read_hashed::<P>(path)?;
    if header.stage != stage {
        return Err(IoError::Artifact {
            path: path.to_path_buf(),
            problem: format!("made by stage '{}', expected '{stage}'", header.stage),
        });
    }
    Ok((header, payload))
}

/// Reads any artifact generically (header plus payload as a CBOR value), for inspection.
pub fn read_any(path: &Path) -> Result<(ArtifactHeader, ciborium::Value), IoError> {
    let bytes = std::fs::read(path).map_err(|source| IoError::Read {
        path: path.to_path_buf(),
        source,
    })?;
    decode(&bytes, path)
}

/// Writes bytes into a uniquely named temporary file beside `path`; returns its path.
fn write_temp(path: &Path, bytes: &[u8]) -> Result<PathBuf, IoError> {
    write_temp_with(path, |f| f.write_all(bytes))
}

/// Creates a uniquely named temporary file beside `path`, lets `fill` write it, and syncs
/// it; returns its path, or removes it on any error.
fn write_temp_with(
    path: &Path,
    fill: impl FnOnce(&mut std::fs::File) -> std::io::Result<()>,
) -> Result<PathBuf, IoError> {
    let (mut f, tmp) = create_temp(path)?;
    let result = fill(&mut f).and_then(|()| f.sync_all());
    if let Err(source) = result {
        let _ = std::fs::remove_file(&tmp);
        return Err(IoError::Write {
            path: path.to_path_buf(),
            source,
        });
    }
    Ok(tmp)
}

/// Creates a uniquely named temporary file beside `path` (and `path`'s folder if need be);
/// returns it open for writing with its path.
///
/// The name carries the process id and a process-wide counter, so threads of one process
/// and concurrent runs never write the same temporary file.
fn create_temp(path: &Path) -> Result<(std::fs::File, PathBuf), IoError> {
    static COUNTER: AtomicU64 = AtomicU64::new(0);
    let err = |source| IoError::Write {
        path: path.to_path_buf(),
        source,
    };
    if path.is_dir() {
        return Err(err(std::io::Error::new(
            std::io::ErrorKind::IsADirectory,
            "a folder is in the way",
        )));
    }
    let dir = path
        .parent()
        .filter(|p| !p.as_os_str().is_empty())
        .unwrap_or(Path::new("."));
    std::fs::create_dir_all(dir).map_err(err)?;
    let name = path
        .file_name()
        .map(|n| n.to_string_lossy().into_owned())
        .unwrap_or_default();
    let n = COUNTER.fetch_add(1, Ordering::Relaxed);
    let tmp = dir.join(format!(".{name}.tmp-{}-{n}", std::process::id()));
    let f = std::fs::File::create(&tmp).map_err(err)?;
    Ok((f, tmp))
}

/// Writes bytes atomically: a uniquely named temporary file beside `path`, then a rename.
///
/// A crash or error leaves either the old file or none, never a half-written one.
pub fn write_atomic(path: &Path, bytes: &[u8]) -> Result<(), IoError> {
    write_atomic_all(&[(path, bytes)])
}

/// Writes several files as a set: every temporary file first, then every rename.
///
/// If any file cannot be written, every temporary file is removed and no destination is
/// touched, so a failure never leaves a new file of the set next to an old one. (A rename
/// failing after earlier renames succeeded can still mix; renames within one folder
/// practically fail only when the folder itself goes away.)
pub fn write_atomic_all(files: &[(&Path, &[u8])]) -> Result<(), IoError> {
    let mut set = FileSet::default();
    for (path, bytes) in files {
        set.add(path, bytes)?;
    }
    set.commit()
}

/// Files written as a set, one at a time as each is made ([`write_atomic_all`] with the
/// bytes of only one file in hand): each goes to a temporary file beside its destination,
/// and [`FileSet::commit`] renames them all into place. A set dropped uncommitted (an
/// error on the way) removes its temporaries and leaves every destination as it was.
#[derive(Debug, Default)]
pub struct FileSet {
    /// (temporary, destination) of every file added.
    temps: Vec<(PathBuf, PathBuf)>,
}

impl FileSet {
    /// Writes `bytes` to a temporary file that [`FileSet::commit`] renames onto `path`.
    pub fn add(&mut self, path: &Path, bytes: &[u8]) -> Result<(), IoError> {
        let tmp = write_temp(path, bytes)?;
        self.temps.push((tmp, path.to_path_buf()));
        Ok(())
    }

    /// Renames every file into place, in the order added.
    pub fn commit(mut self) -> Result<(), IoError> {
        let temps = std::mem::take(&mut self.temps);
        for (i, (tmp, path)) in temps.iter().enumerate() {
            if let Err(source) = std::fs::rename(tmp, path) {
                temps.iter().skip(i).for_each(|(t, _)| {
                    let _ = std::fs::remove_file(t);
                });
                return Err(IoError::Write {
                    path: path.clone(),
                    source,
                });
            }
        }
        Ok(())
    }
}

impl Drop for FileSet {
    fn drop(&mut self) {
        for (tmp, _) in &self.temps {
            let _ = std::fs::remove_file(tmp);
        }
    }
}

/// Renames a temporary file onto `path`, removing it if that fails.
fn rename_into(tmp: &Path, path: &Path) -> Result<(), IoError> {
    std::fs::rename(tmp, path).map_err(|source| {
        let _ = std::fs::remove_file(tmp);
        IoError::Write {
            path: path.to_path_buf(),
            source,
        }
    })
}

/// Encodes and writes an artifact atomically (streamed: see [`write_hashed`]).
pub fn write<P: Serialize>(
    path: &Path,
    header: &ArtifactHeader,
    payload: &P,
) -> Result<(), IoError> {
    write_hashed(path, header, payload).map(|_| ())
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::Trajectories;

    fn header() -> ArtifactHeader {
        ArtifactHeader {
            stage: "mocap-io".into(),
            schema_version: 1,
            tool_version: "0.1.0".into(),
            params: ciborium::Value::Map(vec![]),
            inputs: vec![InputHash {
                role: "capture".into(),
                blake3: content_hash(b"x"),
            }],
        }
    }

    fn sample() -> Trajectories {
        Trajectories::new(
            vec!["A".into(), "B".into()],
            120.0,
            1,
            2,
            vec![
                [1.0, 2.0, 3.0],
                [f64::NAN; 3],
                [4.5, -6.0, 1e9],
                [0.0, 0.0, 0.25],
            ],
        )
        .unwrap()
    }

    #[test]
    fn trajectories_round_trip_through_an_artifact() {
        let t = sample();
        let bytes = encode(&header(), &t).unwrap();
        assert!(bytes.starts_with(&MAGIC));
        let (h, back): (_, Trajectories) = decode(&bytes, Path::new("t.cbor")).unwrap();
        assert_eq!(h, header());
        assert_eq!(back.labels(), t.labels());
        assert_eq!(back.get(0, 1), None);
        assert_eq!(back.get(1, 0), Some([4.5, -6.0, 1e9]));
        assert_eq!(back.missing_samples(), 1);
        // Same value, same bytes: the cache relies on it.
        assert_eq!(encode(&header(), &back).unwrap(), bytes);
    }

    #[test]
    fn bulk_positions_are_one_byte_string() {
        let bytes = encode(&header(), &sample()).unwrap();
        // 4 samples × 3 × 8 bytes = 96 bytes, stored as CBOR bytes of length 96 (0x58 0x60).
        assert!(bytes.windows(2).any(|w| w == [0x58, 96]));
    }

    #[test]
    fn garbage_and_truncation_are_errors_not_panics() {
        let bytes = encode(&header(), &sample()).unwrap();
        for cut in 0..bytes.len() {
            assert!(decode::<Trajectories>(&bytes[..cut], Path::new("t.cbor")).is_err());
        }
        let err = decode::<Trajectories>(b"hello", Path::new("t.cbor")).unwrap_err();
        assert!(err.to_string().contains("t.cbor"), "{err}");
    }

    /// Streamed, an artifact is the bytes `encode` makes and its hash theirs; read back
    /// as it streams in, it is the same value, and the hash covers the whole file.
    #[test]
    fn streamed_artifacts_are_the_encoded_bytes_and_their_hash() {
        let dir = std::env::temp_dir().join(format!("ossify-art-stream-{}", std::process::id()));
        let path = dir.join("s.cbor");
        let bytes = encode(&header(), &sample()).unwrap();
        let hash = write_hashed(&path, &header(), &sample()).unwrap();
        assert_eq!(std::fs::read(&path).unwrap(), bytes);
        assert_eq!(hash, content_hash(&bytes));
        assert_eq!(encoded_hash(&header(), &sample()).unwrap(), hash);
        let (h, t, read_hash) = read_hashed::<Trajectories>(&path).unwrap();
        assert_eq!((h, read_hash), (header(), hash.clone()));
        assert_eq!(encode(&header(), &t).unwrap(), bytes);
        // Trailing bytes decode as before (as `decode` reads a slice) but change the hash.
        let mut longer = bytes.clone();
        longer.extend_from_slice(b"tail");
        std::fs::write(&path, &longer).unwrap();
        let (_, _, tail_hash) = read_hashed::<Trajectories>(&path).unwrap();
        assert_eq!(tail_hash, content_hash(&longer));
        assert_ne!(tail_hash, hash);
        std::fs::remove_dir_all(&dir).unwrap();
    }

    #[test]
    fn streamed_garbage_and_truncation_are_errors_naming_the_file() {
        let dir = std::env::temp_dir().join(format!("ossify-art-cut-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let path = dir.join("cut.cbor");
        let bytes = encode(&header(), &sample()).unwrap();
        for cut in 0..bytes.len() {
            std::fs::write(&path, &bytes[..cut]).unwrap();
            let err = read_hashed::<Trajectories>(&path).unwrap_err().to_string();
            assert!(err.contains("cut.cbor"), "{cut}: {err}");
            // Past the tag, the error says the file was cut, in words.
            assert!(
                cut < MAGIC.len() || err.contains("cut short"),
                "{cut}: {err}"
            );
        }
        std::fs::write(&path, b"hello").unwrap();
        assert!(read_hashed::<Trajectories>(&path).is_err());
        // A byte no CBOR item starts with, where the header's first key should be.
        let mut flipped = bytes.clone();
        flipped[MAGIC.len() + 1] = 0x1c;
        std::fs::write(&path, &flipped).unwrap();
        let err = read_hashed::<Trajectories>(&path).unwrap_err().to_string();
        assert!(err.ends_with("not valid CBOR at byte 4"), "{err}");
        let missing = read_hashed::<Trajectories>(&dir.join("none.cbor")).unwrap_err();
        assert!(missing.to_string().contains("none.cbor"), "{missing}");
        std::fs::remove_dir_all(&dir).unwrap();
    }

    /// The names of the entries of `dir`, sorted (temp files left behind show here).
    fn file_names(dir: &Path) -> Vec<String> {
        let mut names: Vec<String> = std::fs::read_dir(dir)
            .unwrap()
            .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
            .collect();
        names.sort();
        names
    }

    #[test]
    fn atomic_write_leaves_no_temp_file() {
        let dir = std::env::temp_dir().join(format!("ossify-art-{}", std::process::id()));
        let path = dir.join("a.cbor");
        write(&path, &header(), &sample()).unwrap();
        let (_, t): (_, Trajectories) = read(&path, "mocap-io").unwrap();
        assert_eq!(t.frames(), 2);
        assert!(read::<Trajectories>(&path, "segment").is_err());
        let names = file_names(&dir);
        assert_eq!(names.len(), 1, "{names:?}");
        std::fs::remove_dir_all(&dir).unwrap();
    }

    #[test]
    fn threads_writing_one_path_do_not_collide() {
        let dir = std::env::temp_dir().join(format!("ossify-art-race-{}", std::process::id()));
        let path = dir.join("same.bin");
        let contents: Vec<Vec<u8>> = (0..4u8).map(|t| vec![t; 4096]).collect();
        std::thread::scope(|s| {
            for bytes in &contents {
                let path = &path;
                s.spawn(move || {
                    for _ in 0..200 {
                        // With a pid-only temp name, one thread renames another's temp
                        // away and the other's rename fails (or writes mixed bytes).
                        write_atomic(path, bytes).unwrap();
                    }
                });
            }
        });
        let last = std::fs::read(&path).unwrap();
        assert!(contents.contains(&last), "mixed bytes");
        let names = file_names(&dir);
        assert_eq!(names.len(), 1, "{names:?}");
        std::fs::remove_dir_all(&dir).unwrap();
    }

    #[test]
    fn a_set_is_written_whole_or_not_at_all() {
        let dir = std::env::temp_dir().join(format!("ossify-art-set-{}", std::process::id()));
        let (a, b) = (dir.join("a.txt"), dir.join("b.txt"));
        write_atomic_all(&[(&a, b"old a"), (&b, b"old b")]).unwrap();
        // b is now a folder: its temp cannot replace it, so a must stay old.
        std::fs::remove_file(&b).unwrap();
        std::fs::create_dir(&b).unwrap();
        std::fs::write(b.join("keep"), b"x").unwrap();
        let err = write_atomic_all(&[(&a, b"new a"), (&b, b"new b")]).unwrap_err();
        assert!(err.to_string().contains("b.txt"), "{err}");
        assert_eq!(std::fs::read(&a).unwrap(), b"old a");
        assert_eq!(file_names(&dir), ["a.txt", "b.txt"]);
        std::fs::remove_dir_all(&dir).unwrap();
    }
}
