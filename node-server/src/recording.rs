//! The recording file: append-only, crash-safe, self-checking, and readable past damage.
//!
//! Layout: a header — magic `OCELLIRC`, `u16 LE` format version, `u16 LE` name length, the
//! scenario name (UTF-8) — then records, each `u32 LE len | u32 LE crc32(payload) | payload`
//! (payloads are [`Stamped`] records).
//!
//! Crash safety: [`Recorder`] writes each record with a single `write(2)` on an unbuffered
//! file opened `O_APPEND`, so a record that returned is in the kernel and survives a crash of
//! the process; the runtime calls [`Recorder::sync`] on a timer to survive a crash of the host.
//! The recorder holds an exclusive lock on the file: a second server process on the same
//! recording is refused ([`RecordingError::InUse`]). New files are created `0640`.
//!
//! Damage: a crash mid-write leaves a torn tail, and a disk can flip bits anywhere. [`Reader`]
//! skips a damaged stretch by scanning forward, byte by byte, to the next valid record (see
//! [`frames`]) and reports each stretch it skipped as a [`Skipped`]; every valid record before
//! and after it reads back.
//!
//! A recording's bytes are never changed once written, not even a torn tail's:
//! [`Recorder::resume`] appends after whatever the file ends with, and readers resynchronise
//! past it. Cutting the tail off (or moving it to a side file first) would be a second,
//! non-atomic write path that a crash could interrupt, and it would need a rule for telling a
//! torn tail from damage mid-file; leaving the bytes in place keeps everything, and costs each
//! later reader one skip that it reports. The one exception is a file too short to hold its
//! header: if its bytes begin the header this server would write, the rest of the header is
//! appended; otherwise the file is renamed aside (`<file>.damaged-<n>`) and a new one started.

mod frames;
mod recorder;
#[cfg(test)]
mod tests;

use crate::record::{RecordError, Stamped};
use serde::Serialize;
use std::fs::File;
use std::io::{BufReader, Read};
use std::path::{Path, PathBuf};
use thiserror::Error;

pub(crate) use frames::{FRAME_HEADER, Step, next_valid, step};
pub use recorder::Recorder;

/// File magic.
pub const MAGIC: [u8; 8] = *b"OCELLIRC";
/// Format version of the recording file. Records hold wire envelopes, so it moves with
/// `proto::PROTOCOL_VERSION`: format N was recorded with protocol N (7: heads tell the server the
/// tags they hear and are told each tag's home; 6: priors say whether a
/// track is a radio track; 5: nodes answer a step's priors in one message; 4: track reports
/// carry their frames' capture time, cameras send people frames).
pub const FORMAT_VERSION: u16 = 7;
/// Largest record payload accepted; a length beyond it is corruption, not an allocation.
pub const MAX_RECORD_BYTES: u32 = 16 * 1024 * 1024;
/// Permissions of a new recording: not world-readable (further narrowed by the umask).
pub const FILE_MODE: u32 = 0o640;
/// Bytes a [`Reader`] reads ahead at a time.
const READ_AHEAD: usize = 64 * 1024;

/// A recording that cannot be opened or written.
#[derive(Debug, Error)]
pub enum RecordingError {
    #[error("recording {path}: {source}")]
    Io { path: PathBuf, source: std::io::Error },
    #[error("recording {path}: not an Ocelli recording (bad magic)")]
    BadMagic { path: PathBuf },
    #[error(
        "recording {path}: recorded with protocol {got} (format version {got}); this build reads protocol {FORMAT_VERSION} \
         only: use the Ocelli release that made it"
    )]
    Version { path: PathBuf, got: u16 },
    #[error("recording {path}: header is truncated")]
    TruncatedHeader { path: PathBuf },
    #[error("recording {path}: record at byte {offset}: {source}")]
    Record {
        path: PathBuf,
        offset: u64,
        source: RecordError,
    },
    #[error("recording {path}: a record payload of {bytes} bytes is outside 1..={MAX_RECORD_BYTES}")]
    RecordSize { path: PathBuf, bytes: usize },
    #[error("recording {path} is in use by another process (it holds the file's lock)")]
    InUse { path: PathBuf },
    #[error("scenario name of {0} bytes is too long for the header")]
    NameTooLong(usize),
}

/// What was wrong where a reader had to skip.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
#[serde(rename_all = "kebab-case", tag = "kind")]
pub enum Damage {
    /// The data ends inside a record's 8-byte frame header.
    ShortHeader,
    /// The data ends inside a record's payload.
    ShortPayload { len: u32 },
    /// The length field is zero or beyond [`MAX_RECORD_BYTES`].
    BadLength { len: u32 },
    /// The payload does not match its CRC.
    Checksum,
    /// The frame is intact (its CRC holds) but its payload is not a record this build knows.
    Undecodable,
}

/// One stretch of a recording that a reader skipped: where it starts, how long it is, and
/// what was wrong at its start. Adjacent skips are merged into one.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
pub struct Skipped {
    pub offset: u64,
    pub bytes: u64,
    pub damage: Damage,
}

/// Add a skip to a list, merging it into the last one when they touch.
pub(crate) fn note_skip(list: &mut Vec<Skipped>, offset: u64, bytes: u64, damage: Damage) {
    match list.last_mut() {
        Some(last) if last.offset + last.bytes == offset => last.bytes += bytes,
        _ => list.push(Skipped {
            offset,
            bytes,
            damage,
        }),
    }
}

/// Total bytes of a list of skips.
pub fn skipped_bytes(list: &[Skipped]) -> u64 {
    list.iter().map(|s| s.bytes).sum()
}

/// Streaming reader of a recording's records; skips damage and remembers what it skipped.
#[derive(Debug)]
pub struct Reader<R> {
    inner: R,
    path: PathBuf,
    name: String,
    /// Bytes of the file (the reader reads no further).
    len: u64,
    /// Bytes read from `inner` but not consumed yet start at `buf[start]`, file offset `offset`.
    buf: Vec<u8>,
    start: usize,
    offset: u64,
    skipped: Vec<Skipped>,
    records: u64,
}

pub(crate) fn io(path: &Path) -> impl FnOnce(std::io::Error) -> RecordingError + '_ {
    move |source| RecordingError::Io {
        path: path.into(),
        source,
    }
}

fn header_bytes(name: &str) -> Result<Vec<u8>, RecordingError> {
    let n = u16::try_from(name.len()).map_err(|_| RecordingError::NameTooLong(name.len()))?;
    let mut h = MAGIC.to_vec();
    h.extend_from_slice(&FORMAT_VERSION.to_le_bytes());
    h.extend_from_slice(&n.to_le_bytes());
    h.extend_from_slice(name.as_bytes());
    Ok(h)
}

impl Reader<BufReader<File>> {
    /// Open a recording file and read its header.
    ///
    /// # Errors
    /// IO errors, a wrong magic or version, or a header cut short.
    pub fn open(path: &Path) -> Result<Self, RecordingError> {
        let file = File::open(path).map_err(io(path))?;
        let len = file.metadata().map_err(io(path))?.len();
        Reader::new(BufReader::new(file), len, path)
    }
}

impl<R: Read> Reader<R> {
    /// Read the header of a recording of `len` bytes from `inner`; `path` names it in errors.
    ///
    /// # Errors
    /// As [`Reader::open`].
    pub fn new(mut inner: R, len: u64, path: &Path) -> Result<Self, RecordingError> {
        let Some((name, offset)) = read_header(&mut inner, path)? else {
            return Err(RecordingError::TruncatedHeader { path: path.into() });
        };
        Ok(Reader {
            inner,
            path: path.into(),
            name,
            len: len.max(offset),
            buf: Vec::new(),
            start: 0,
            offset,
            skipped: Vec::new(),
            records: 0,
        })
    }

    /// Scenario name from the header.
    pub fn name(&self) -> &str {
        &self.name
    }

    /// The stretches skipped so far, in file order.
    pub fn skipped(&self) -> &[Skipped] {
        &self.skipped
    }

    /// File offset of the first byte not read yet (header, records and skips behind it).
    pub fn offset(&self) -> u64 {
        self.offset
    }

    /// Records read so far.
    pub fn records(&self) -> u64 {
        self.records
    }

    /// Make at least `want` unconsumed bytes available, or all that is left of the file.
    fn fill(&mut self, want: usize) -> Result<(), RecordingError> {
        let have = self.buf.len() - self.start;
        let end = self.offset + have as u64;
        if have >= want || end >= self.len {
            return Ok(());
        }
        if self.start > 0 {
            self.buf.drain(..self.start);
            self.start = 0;
        }
        let ask = (want - have).max(READ_AHEAD) as u64;
        let ask = ask.min(self.len - end);
        let got = (&mut self.inner)
            .take(ask)
            .read_to_end(&mut self.buf)
            .map_err(io(&self.path))?;
        if (got as u64) < ask {
            // The file is shorter than it was said to be: its end is here.
            self.len = end + got as u64;
        }
        Ok(())
    }

    fn consume(&mut self, n: usize) {
        self.start += n;
        self.offset += n as u64;
    }

    /// The next valid record, skipping (and noting) damage; `None` at the end.
    ///
    /// # Errors
    /// IO errors only.
    pub fn next_record(&mut self) -> Result<Option<Stamped>, RecordingError> {
        let mut want = READ_AHEAD;
        loop {
            self.fill(want)?;
            let window = &self.buf[self.start..];
            let at_end = self.offset + window.len() as u64 >= self.len;
            match step(window, at_end) {
                Step::End => return Ok(None),
                Step::Record { record, frame_len } => {
                    self.consume(frame_len);
                    self.records += 1;
                    return Ok(Some(record));
                }
                Step::Skip { bytes, damage } => {
                    note_skip(&mut self.skipped, self.offset, bytes as u64, damage);
                    self.consume(bytes);
                    want = READ_AHEAD;
                }
                // `need` is more than the window holds and the file has more: fill reads some.
                Step::NeedMore { need, .. } => want = need,
            }
        }
    }
}

impl<R: Read> Iterator for Reader<R> {
    type Item = Result<Stamped, RecordingError>;

    /// The next valid record; damage is skipped and noted in [`Reader::skipped`].
    fn next(&mut self) -> Option<Self::Item> {
        self.next_record().transpose()
    }
}

/// Fill `buf`; `Ok(false)` if the input ended first.
pub(crate) fn read_full(r: &mut impl Read, buf: &mut [u8]) -> std::io::Result<bool> {
    let mut got = 0;
    while got < buf.len() {
        match r.read(&mut buf[got..]) {
            Ok(0) => return Ok(false),
            Ok(n) => got += n,
            Err(e) if e.kind() == std::io::ErrorKind::Interrupted => {}
            Err(e) => return Err(e),
        }
    }
    Ok(true)
}

/// Everything read back from an existing recording.
#[derive(Debug)]
pub struct ReadBack {
    pub name: String,
    /// Every valid record, in file order.
    pub records: Vec<Stamped>,
    /// The damaged stretches skipped, in file order.
    pub skipped: Vec<Skipped>,
    /// Bytes read (the file's length when it was read).
    pub len: u64,
}

impl ReadBack {
    /// Total bytes skipped.
    pub fn skipped_bytes(&self) -> u64 {
        skipped_bytes(&self.skipped)
    }
}

/// Read all records from `reader`.
fn read_back<R: Read>(mut reader: Reader<R>) -> Result<ReadBack, RecordingError> {
    let mut records = Vec::new();
    while let Some(r) = reader.next_record()? {
        records.push(r);
    }
    Ok(ReadBack {
        name: reader.name,
        records,
        skipped: reader.skipped,
        len: reader.offset,
    })
}

/// Read a whole recording into memory, skipping damage.
///
/// # Errors
/// As [`Reader::open`].
pub fn read_all(path: &Path) -> Result<ReadBack, RecordingError> {
    read_back(Reader::open(path)?)
}

/// Read a recording held in memory (`path` names it in errors), skipping damage.
///
/// # Errors
/// A wrong magic or version, or a header cut short.
pub fn read_bytes(bytes: &[u8], path: &Path) -> Result<ReadBack, RecordingError> {
    read_back(Reader::new(bytes, bytes.len() as u64, path)?)
}

/// The header's scenario name and byte length; `None` while it is not all written.
pub(crate) fn read_header(
    input: &mut impl Read,
    path: &Path,
) -> Result<Option<(String, u64)>, RecordingError> {
    let mut fixed = [0u8; 12];
    if !read_full(input, &mut fixed).map_err(io(path))? {
        return Ok(None);
    }
    if fixed[..8] != MAGIC {
        return Err(RecordingError::BadMagic { path: path.into() });
    }
    let version = u16::from_le_bytes([fixed[8], fixed[9]]);
    if version != FORMAT_VERSION {
        return Err(RecordingError::Version {
            path: path.into(),
            got: version,
        });
    }
    let mut name = vec![0u8; usize::from(u16::from_le_bytes([fixed[10], fixed[11]]))];
    if !read_full(input, &mut name).map_err(io(path))? {
        return Ok(None);
    }
    Ok(Some((
        String::from_utf8_lossy(&name).into_owned(),
        12 + name.len() as u64,
    )))
}
