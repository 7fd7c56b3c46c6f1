//! Artifacts whose payload is a map of names to byte strings (export's output files),
//! written and read one entry at a time, so only one entry's bytes are ever in memory.
//!
//! The payload is `{ field: { name: bytes, ... } }`: a struct of one `BTreeMap<String,
//! ByteBuf>` field, as serde and ciborium encode it. Entries go in increasing name order
//! and their number is given up front, so the bytes are exactly those [`super::encode`]
//! makes of the same value, and [`super::read_hashed`] decodes them as that struct.

use std::io::{BufReader, BufWriter, Read, Write};
use std::path::{Path, PathBuf};

use super::{
    ArtifactHeader, Hashing, MAGIC, STREAM_BUFFER, cbor_problem, create_temp, io_problem,
    read_up_to, rename_into,
};
use crate::error::IoError;

/// CBOR major types this layout uses (RFC 8949 §3.1).
const BYTES: u8 = 2;
const TEXT: u8 = 3;
const MAP: u8 = 5;

/// The shortest CBOR head of a major type with argument `n`, as ciborium writes it.
fn head(major: u8, n: u64) -> Vec<u8> {
    let m = major << 5;
    match n {
        0..=23 => vec![m | n as u8],
        24..=0xff => vec![m | 24, n as u8],
        0x100..=0xffff => [vec![m | 25], (n as u16).to_be_bytes().to_vec()].concat(),
        0x1_0000..=0xffff_ffff => [vec![m | 26], (n as u32).to_be_bytes().to_vec()].concat(),
        _ => [vec![m | 27], n.to_be_bytes().to_vec()].concat(),
    }
}

/// A CBOR text string.
fn text(s: &str) -> Vec<u8> {
    [head(TEXT, s.len() as u64), s.as_bytes().to_vec()].concat()
}

/// An artifact of a byte map written entry by entry ([`ByteMapWriter::push`]).
///
/// The content hash is always known; the file is written where it can be: a failure to
/// write it is kept for [`ByteMapWriter::finish`] to report (a cache entry not written is
/// a warning, not a failed run) and the temporary file is removed. Dropped unfinished, it
/// leaves no file.
#[derive(Debug)]
pub struct ByteMapWriter {
    /// Where the artifact goes.
    path: PathBuf,
    /// The temporary file and its path, until finished or failed.
    file: Option<(BufWriter<std::fs::File>, PathBuf)>,
    hasher: blake3::Hasher,
    /// The first write failure.
    failed: Option<IoError>,
    /// Entries still to come.
    left: usize,
    /// The last entry's name (names must increase).
    last: Option<String>,
}

impl ByteMapWriter {
    /// Starts the artifact at `path` with its header and a payload of `entries` entries
    /// under `field`.
    pub fn create(path: &Path, header: &ArtifactHeader, field: &str, entries: usize) -> Self {
        let (file, failed) = match create_temp(path) {
            Ok((f, tmp)) => (
                Some((BufWriter::with_capacity(STREAM_BUFFER, f), tmp)),
                None,
            ),
            Err(e) => (None, Some(e)),
        };
        let mut w = Self {
            path: path.to_path_buf(),
            file,
            hasher: blake3::Hasher::new(),
            failed,
            left: entries,
            last: None,
        };
        let mut encoded_header = Vec::new();
        // A header is a few hundred bytes of plain values: it always encodes.
        if let Err(e) = ciborium::into_writer(header, &mut encoded_header) {
            w.fail(std::io::Error::other(format!(
                "cannot encode the header: {e}"
            )));
        }
        // Tag 55799, then the envelope {"header": …, "payload": {field: {…}}}.
        let opening = [
            MAGIC.to_vec(),
            head(MAP, 2),
            text("header"),
            encoded_header,
            text("payload"),
            head(MAP, 1),
            text(field),
            head(MAP, entries as u64),
        ]
        .concat();
        w.put(&opening);
        w
    }

    /// Appends one entry; names must come in increasing order, `entries` of them in all.
    pub fn push(&mut self, name: &str, bytes: &[u8]) -> Result<(), IoError> {
        if self.left == 0 {
            return Err(IoError::Invalid(format!(
                "{}: entry {name:?} beyond the number announced",
                self.path.display()
            )));
        }
        if self.last.as_deref().is_some_and(|last| last >= name) {
            return Err(IoError::Invalid(format!(
                "{}: entry {name:?} after {:?}: names must increase",
                self.path.display(),
                self.last.as_deref().unwrap_or_default()
            )));
        }
        self.put(&text(name));
        self.put(&head(BYTES, bytes.len() as u64));
        self.put(bytes);
        self.left -= 1;
        self.last = Some(name.to_owned());
        Ok(())
    }

    /// Ends the artifact: its content hash, and whether the file was written (renamed
    /// into place) or why not. Fewer entries than announced is an error and no file.
    pub fn finish(mut self) -> (String, Result<(), IoError>) {
        let hash = self.hasher.finalize().to_hex().to_string();
        if self.left > 0 {
            let missing = IoError::Invalid(format!(
                "{}: {} announced entries never came",
                self.path.display(),
                self.left
            ));
            return (hash, Err(missing));
        }
        if let Some(e) = self.failed.take() {
            return (hash, Err(e));
        }
        let Some((mut out, tmp)) = self.file.take() else {
            return (hash, Ok(()));
        };
        let synced = out
            .flush()
            .and_then(|()| out.get_ref().sync_all())
            .map_err(|source| IoError::Write {
                path: self.path.clone(),
                source,
            });
        drop(out);
        let written = match synced {
            Ok(()) => rename_into(&tmp, &self.path),
            Err(e) => {
                let _ = std::fs::remove_file(&tmp);
                Err(e)
            }
        };
        (hash, written)
    }

    /// Hashes `bytes` and writes them to the file while it can.
    fn put(&mut self, bytes: &[u8]) {
        self.hasher.update(bytes);
        if let Some((out, _)) = &mut self.file
            && let Err(e) = out.write_all(bytes)
        {
            self.fail(e);
        }
    }

    /// Keeps the first failure and gives the file up.
    fn fail(&mut self, source: std::io::Error) {
        if let Some((_, tmp)) = self.file.take() {
            let _ = std::fs::remove_file(&tmp);
        }
        self.failed.get_or_insert(IoError::Write {
            path: self.path.clone(),
            source,
        });
    }
}

impl Drop for ByteMapWriter {
    fn drop(&mut self) {
        if let Some((_, tmp)) = self.file.take() {
            let _ = std::fs::remove_file(&tmp);
        }
    }
}

/// Any artifact's header and the [`super::content_hash`] of the whole file, its payload
/// hashed as it streams past but not decoded: what a cache needs to key the stages after
/// an entry it may never have to read. A damaged payload shows only when it is decoded.
pub fn read_header_hashed(path: &Path) -> Result<(ArtifactHeader, String), IoError> {
    let (r, header) = ByteMapReader::open_header(path)?;
    Ok((header, r.finish()?))
}

/// An artifact of a byte map read entry by entry, as it streams in.
#[derive(Debug)]
pub struct ByteMapReader {
    path: PathBuf,
    input: Hashing<BufReader<std::fs::File>>,
    /// Entries still to read.
    left: u64,
}

impl ByteMapReader {
    /// Opens the artifact at `path` and reads its header, up to the first entry of the
    /// map under `field`.
    pub fn open(path: &Path, field: &str) -> Result<(Self, ArtifactHeader), IoError> {
        let (mut r, header) = Self::open_header(path)?;
        r.expect_text("payload")?;
        r.expect_head(MAP, 1, "the payload")?;
        r.expect_text(field)?;
        r.left = r.read_head(MAP, "the entries")?;
        Ok((r, header))
    }

    /// Opens any artifact and reads its header, up to its payload.
    fn open_header(path: &Path) -> Result<(Self, ArtifactHeader), IoError> {
        let file = std::fs::File::open(path).map_err(|source| IoError::Read {
            path: path.to_path_buf(),
            source,
        })?;
        let mut r = Self {
            path: path.to_path_buf(),
            input: Hashing::new(BufReader::with_capacity(STREAM_BUFFER, file)),
            left: 0,
        };
        let mut magic = [0u8; MAGIC.len()];
        let got = read_up_to(&mut r.input, &mut magic).map_err(|e| r.bad(e.to_string()))?;
        if magic[..got] != MAGIC {
            return Err(r.bad(
                "missing the CBOR self-describe tag (d9 d9 f7) that opens every artifact".into(),
            ));
        }
        r.expect_head(MAP, 2, "the envelope")?;
        r.expect_text("header")?;
        // The header starts after the tag (3 bytes), the envelope's head (1) and its key
        // (7): where a decoding error counts its bytes from.
        let header: ArtifactHeader = ciborium::from_reader(&mut r.input)
            .map_err(|e| r.bad(format!("header: {}", cbor_problem(&e, 11, io_problem))))?;
        Ok((r, header))
    }

    /// The next entry's name and bytes; `None` after the last.
    pub fn next_entry(&mut self) -> Result<Option<(String, Vec<u8>)>, IoError> {
        if self.left == 0 {
            return Ok(None);
        }
        let len = self.read_head(TEXT, "an entry's name")?;
        let name = String::from_utf8(self.read_exact_len(len, "an entry's name")?)
            .map_err(|_| self.bad("an entry's name is not UTF-8".into()))?;
        let len = self.read_head(BYTES, "an entry's bytes")?;
        let bytes = self.read_exact_len(len, &name)?;
        self.left -= 1;
        Ok(Some((name, bytes)))
    }

    /// The content hash of the whole file (bytes after the payload too), once every entry
    /// was read.
    pub fn finish(mut self) -> Result<String, IoError> {
        if self.left > 0 {
            return Err(self.bad(format!("{} entries left unread", self.left)));
        }
        std::io::copy(&mut self.input, &mut std::io::sink())
            .map_err(|e| self.bad(e.to_string()))?;
        Ok(self.input.hash())
    }

    fn bad(&self, problem: String) -> IoError {
        IoError::Artifact {
            path: self.path.clone(),
            problem,
        }
    }

    /// Reads a CBOR head of major type `major` with a definite argument.
    fn read_head(&mut self, major: u8, what: &str) -> Result<u64, IoError> {
        let mut first = [0u8; 1];
        self.fill(&mut first, what)?;
        let info = first[0] & 0x1f;
        if first[0] >> 5 != major || info > 27 {
            return Err(self.bad(format!(
                "{what}: unexpected CBOR item (initial byte {:#04x})",
                first[0]
            )));
        }
        if info < 24 {
            return Ok(u64::from(info));
        }
        let mut arg = [0u8; 8];
        let width = 1usize << (info - 24);
        self.fill(&mut arg[8 - width..], what)?;
        Ok(u64::from_be_bytes(arg))
    }

    fn expect_head(&mut self, major: u8, n: u64, what: &str) -> Result<(), IoError> {
        let got = self.read_head(major, what)?;
        if got != n {
            return Err(self.bad(format!("{what}: {got} entries, expected {n}")));
        }
        Ok(())
    }

    fn expect_text(&mut self, expected: &str) -> Result<(), IoError> {
        let what = format!("the key {expected:?}");
        let len = self.read_head(TEXT, &what)?;
        let got = self.read_exact_len(len, &what)?;
        if got != expected.as_bytes() {
            return Err(self.bad(format!(
                "{what} expected, found {:?}",
                String::from_utf8_lossy(&got)
            )));
        }
        Ok(())
    }

    /// Reads `len` bytes, growing as they come (a damaged length cannot allocate wildly).
    fn read_exact_len(&mut self, len: u64, what: &str) -> Result<Vec<u8>, IoError> {
        let mut out = Vec::new();
        (&mut self.input)
            .take(len)
            .read_to_end(&mut out)
            .map_err(|e| self.bad(format!("{what}: {e}")))?;
        if (out.len() as u64) < len {
            return Err(self.bad(format!("{what}: the file ends inside it")));
        }
        Ok(out)
    }

    fn fill(&mut self, buf: &mut [u8], what: &str) -> Result<(), IoError> {
        let got = read_up_to(&mut self.input, buf).map_err(|e| self.bad(e.to_string()))?;
        if got < buf.len() {
            return Err(self.bad(format!("{what}: the file ends inside it")));
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use std::collections::BTreeMap;

    use serde::{Deserialize, Serialize};

    use super::super::{InputHash, encode, read_hashed};
    use super::*;

    /// The payload as serde sees it: export's `Outputs`.
    #[derive(Debug, PartialEq, Serialize, Deserialize)]
    struct Files {
        files: BTreeMap<String, serde_bytes::ByteBuf>,
    }

    fn header() -> ArtifactHeader {
        ArtifactHeader {
            stage: "export".into(),
            schema_version: 3,
            tool_version: "0.1.0".into(),
            params: ciborium::Value::Map(vec![]),
            inputs: vec![InputHash {
                role: "bonefit".into(),
                blake3: super::super::content_hash(b"x"),
            }],
        }
    }

    /// Entries of every head width a length takes: 0, < 24, 1, 2 and 4 bytes.
    fn entries() -> Vec<(String, Vec<u8>)> {
        [0usize, 5, 24, 300, 70_000]
            .into_iter()
            .enumerate()
            .map(|(i, n)| {
                (
                    format!("f{i}.bin"),
                    (0..n).map(|b| (b * 7 + i) as u8).collect(),
                )
            })
            .collect()
    }

    fn scratch(tag: &str) -> PathBuf {
        let dir = std::env::temp_dir().join(format!("ossify-bytemap-{tag}-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&dir);
        std::fs::create_dir_all(&dir).unwrap();
        dir
    }

    fn write_all(path: &Path) -> String {
        let list = entries();
        let mut w = ByteMapWriter::create(path, &header(), "files", list.len());
        for (name, bytes) in &list {
            w.push(name, bytes).unwrap();
        }
        let (hash, written) = w.finish();
        written.unwrap();
        hash
    }

    #[test]
    fn streamed_entries_are_the_bytes_serde_makes_and_read_back_one_by_one() {
        let dir = scratch("same");
        let path = dir.join("e.cbor");
        let hash = write_all(&path);
        let whole = Files {
            files: entries()
                .into_iter()
                .map(|(n, b)| (n, serde_bytes::ByteBuf::from(b)))
                .collect(),
        };
        let bytes = encode(&header(), &whole).unwrap();
        assert_eq!(std::fs::read(&path).unwrap(), bytes);
        assert_eq!(hash, super::super::content_hash(&bytes));
        let (h, back, read_hash) = read_hashed::<Files>(&path).unwrap();
        assert_eq!((h, &back, &read_hash), (header(), &whole, &hash));

        let (mut r, h) = ByteMapReader::open(&path, "files").unwrap();
        assert_eq!(h, header());
        let mut got = Vec::new();
        while let Some(e) = r.next_entry().unwrap() {
            got.push(e);
        }
        assert_eq!(got, entries());
        assert_eq!(r.finish().unwrap(), hash);
        std::fs::remove_dir_all(&dir).unwrap();
    }

    #[test]
    fn any_artifacts_header_and_hash_come_without_its_payload() {
        let dir = scratch("header");
        let path = dir.join("e.cbor");
        let hash = write_all(&path);
        assert_eq!(read_header_hashed(&path).unwrap(), (header(), hash));
        let other = dir.join("t.cbor");
        let bytes = encode(&header(), &[1.5f64, 2.5]).unwrap();
        std::fs::write(&other, &bytes).unwrap();
        let expected = (header(), super::super::content_hash(&bytes));
        assert_eq!(read_header_hashed(&other).unwrap(), expected);
        std::fs::write(&other, &bytes[..20]).unwrap();
        let err = read_header_hashed(&other).unwrap_err().to_string();
        assert!(err.contains("t.cbor"), "{err}");
        std::fs::remove_dir_all(&dir).unwrap();
    }

    #[test]
    fn out_of_order_too_many_or_too_few_entries_are_refused_and_leave_no_file() {
        let dir = scratch("order");
        let path = dir.join("o.cbor");
        let mut w = ByteMapWriter::create(&path, &header(), "files", 2);
        w.push("b", b"1").unwrap();
        assert!(w.push("a", b"2").is_err());
        assert!(w.push("b", b"2").is_err());
        w.push("c", b"3").unwrap();
        assert!(w.push("d", b"4").is_err());
        let (_, written) = w.finish();
        written.unwrap();
        let few = ByteMapWriter::create(&dir.join("few.cbor"), &header(), "files", 2);
        assert!(few.finish().1.is_err());
        let dropped = ByteMapWriter::create(&dir.join("dropped.cbor"), &header(), "files", 1);
        drop(dropped);
        let left: Vec<_> = std::fs::read_dir(&dir)
            .unwrap()
            .map(|e| e.unwrap().file_name())
            .collect();
        assert_eq!(left, ["o.cbor"]);
        std::fs::remove_dir_all(&dir).unwrap();
    }

    /// A file that cannot be written still gives the hash, and says why it was not written.
    #[test]
    fn an_unwritable_destination_still_hashes() {
        let dir = scratch("unwritable");
        let good = dir.join("good.cbor");
        let hash = write_all(&good);
        let blocked = dir.join("blocked.cbor");
        std::fs::create_dir(&blocked).unwrap();
        let list = entries();
        let mut w = ByteMapWriter::create(&blocked, &header(), "files", list.len());
        for (name, bytes) in &list {
            w.push(name, bytes).unwrap();
        }
        let (blocked_hash, written) = w.finish();
        assert_eq!(blocked_hash, hash);
        let err = written.unwrap_err().to_string();
        assert!(err.contains("blocked.cbor"), "{err}");
        std::fs::remove_dir_all(&dir).unwrap();
    }

    #[test]
    fn truncated_or_foreign_files_are_errors_naming_the_file() {
        let dir = scratch("cut");
        let path = dir.join("e.cbor");
        write_all(&path);
        let bytes = std::fs::read(&path).unwrap();
        let cut = dir.join("cut.cbor");
        for n in (0..bytes.len()).step_by(97).chain([bytes.len() - 1]) {
            std::fs::write(&cut, &bytes[..n]).unwrap();
            let result = ByteMapReader::open(&cut, "files").and_then(|(mut r, _)| {
                while r.next_entry()?.is_some() {}
                r.finish()
            });
            let err = result.unwrap_err().to_string();
            assert!(err.contains("cut.cbor"), "{n}: {err}");
        }
        let err = ByteMapReader::open(&path, "other").unwrap_err().to_string();
        assert!(err.contains("\"other\""), "{err}");
        std::fs::write(&cut, b"hello").unwrap();
        assert!(ByteMapReader::open(&cut, "files").is_err());
        std::fs::remove_dir_all(&dir).unwrap();
    }
}
