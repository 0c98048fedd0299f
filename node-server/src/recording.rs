//! The recording file: append-only, crash-safe, self-checking.
//!
//! Layout: a header — magic `OCELLIRC`, `u16 LE` format version, `u16 LE` name length, the
//! scenario name (UTF-8) — then records, each `u32 LE len | u32 LE crc32(payload) | payload`
//! (payloads are [`Stamped`] records).
//!
//! Crash safety: [`Recorder`] writes each record with a single `write(2)` on an unbuffered
//! file, so a record that returned is in the kernel and survives a crash of the process; the
//! runtime calls [`Recorder::sync`] on a timer to survive a crash of the host. A crash mid-write
//! leaves a torn tail: [`Reader`] stops at the first record that is short or fails its CRC,
//! reports how many bytes it skipped, and everything before it reads back intact.
//! [`Recorder::resume`] truncates the torn tail before appending, so new records never hide
//! behind it.

use crate::record::{RecordError, Stamped};
use std::fs::{File, OpenOptions};
use std::io::{BufReader, Read, Seek, SeekFrom, Write};
use std::path::{Path, PathBuf};
use thiserror::Error;

/// File magic.
pub const MAGIC: [u8; 8] = *b"OCELLIRC";
/// Format version of the recording file. Records hold wire envelopes, so it moves with
/// `proto::PROTOCOL_VERSION`: format 1 was recorded with protocol 1, format 2 with protocol 2.
pub const FORMAT_VERSION: u16 = 2;
/// Largest record payload accepted; a length beyond it is corruption, not an allocation.
pub const MAX_RECORD_BYTES: u32 = 16 * 1024 * 1024;

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
    #[error("scenario name of {0} bytes is too long for the header")]
    NameTooLong(usize),
}

/// Why reading stopped before the end of the file.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum TailProblem {
    /// The file ends inside a record's 8-byte frame header.
    ShortHeader,
    /// The file ends inside a record's payload.
    ShortPayload { len: u32 },
    /// The length field is beyond [`MAX_RECORD_BYTES`] or zero.
    BadLength { len: u32 },
    /// The payload does not match its CRC.
    Checksum,
}

/// A torn or corrupt tail: where it starts and how many bytes were skipped.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Tail {
    pub offset: u64,
    pub skipped_bytes: u64,
    pub problem: TailProblem,
}

/// Streaming reader of a recording's records.
#[derive(Debug)]
pub struct Reader<R> {
    inner: R,
    path: PathBuf,
    name: String,
    offset: u64,
    len: u64,
    tail: Option<Tail>,
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
            offset,
            len,
            tail: None,
            records: 0,
        })
    }

    /// Scenario name from the header.
    pub fn name(&self) -> &str {
        &self.name
    }

    /// Where the torn tail starts, once reading hit it.
    pub fn tail(&self) -> Option<&Tail> {
        self.tail.as_ref()
    }

    /// Byte length of the intact part read so far (header + whole, valid records).
    pub fn valid_len(&self) -> u64 {
        self.offset
    }

    /// Records read so far.
    pub fn records(&self) -> u64 {
        self.records
    }

    fn torn(&mut self, problem: TailProblem) {
        self.tail = Some(Tail {
            offset: self.offset,
            skipped_bytes: self.len.saturating_sub(self.offset),
            problem,
        });
    }

    /// The next record's raw payload; `None` at the end or at a torn tail.
    ///
    /// # Errors
    /// IO errors only.
    pub fn next_payload(&mut self) -> Result<Option<Vec<u8>>, RecordingError> {
        if self.tail.is_some() || self.offset >= self.len {
            return Ok(None);
        }
        let mut head = [0u8; 8];
        let path = self.path.clone();
        if !read_full(&mut self.inner, &mut head).map_err(io(&path))? {
            self.torn(TailProblem::ShortHeader);
            return Ok(None);
        }
        let len = u32::from_le_bytes([head[0], head[1], head[2], head[3]]);
        let crc = u32::from_le_bytes([head[4], head[5], head[6], head[7]]);
        if len == 0 || len > MAX_RECORD_BYTES {
            self.torn(TailProblem::BadLength { len });
            return Ok(None);
        }
        if self.offset + 8 + u64::from(len) > self.len {
            self.torn(TailProblem::ShortPayload { len });
            return Ok(None);
        }
        let mut payload = vec![0u8; len as usize];
        if !read_full(&mut self.inner, &mut payload).map_err(io(&path))? {
            self.torn(TailProblem::ShortPayload { len });
            return Ok(None);
        }
        if crc32fast::hash(&payload) != crc {
            self.torn(TailProblem::Checksum);
            return Ok(None);
        }
        self.offset += 8 + u64::from(len);
        self.records += 1;
        Ok(Some(payload))
    }
}

impl<R: Read> Iterator for Reader<R> {
    type Item = Result<Stamped, RecordingError>;

    /// The next decoded record. A record whose CRC holds but whose payload does not decode is an
    /// error (it was written by another build), not a torn tail.
    fn next(&mut self) -> Option<Self::Item> {
        let offset = self.offset;
        match self.next_payload() {
            Err(e) => Some(Err(e)),
            Ok(None) => None,
            Ok(Some(p)) => Some(Stamped::decode(&p).map_err(|source| RecordingError::Record {
                path: self.path.clone(),
                offset,
                source,
            })),
        }
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
    pub records: Vec<Stamped>,
    pub valid_len: u64,
    pub tail: Option<Tail>,
}

/// Read a whole recording into memory.
///
/// # Errors
/// As [`Reader::open`], plus a record that does not decode.
pub fn read_all(path: &Path) -> Result<ReadBack, RecordingError> {
    let mut reader = Reader::open(path)?;
    let mut records = Vec::new();
    for r in reader.by_ref() {
        records.push(r?);
    }
    Ok(ReadBack {
        name: reader.name().to_owned(),
        records,
        valid_len: reader.valid_len(),
        tail: reader.tail().cloned(),
    })
}

/// The append side of a recording.
#[derive(Debug)]
pub struct Recorder {
    file: File,
    path: PathBuf,
    written: u64,
    bytes: u64,
}

impl Recorder {
    /// Create a new recording (fails if the file exists).
    ///
    /// # Errors
    /// IO errors (including an existing file) and an over-long name.
    pub fn create(path: &Path, scenario_name: &str) -> Result<Self, RecordingError> {
        let header = header_bytes(scenario_name)?;
        let mut file = OpenOptions::new()
            .write(true)
            .create_new(true)
            .open(path)
            .map_err(io(path))?;
        file.write_all(&header).map_err(io(path))?;
        file.sync_data().map_err(io(path))?;
        Ok(Recorder {
            file,
            path: path.into(),
            written: 0,
            bytes: header.len() as u64,
        })
    }

    /// Reopen an existing recording: read it back, cut off a torn tail, and append from there.
    /// A file whose header never made it to disk is started afresh.
    ///
    /// # Errors
    /// IO errors, a file that is not a recording, or a record that does not decode.
    pub fn resume(path: &Path, scenario_name: &str) -> Result<(Self, ReadBack), RecordingError> {
        let back = match read_all(path) {
            Err(RecordingError::TruncatedHeader { .. }) => {
                std::fs::remove_file(path).map_err(io(path))?;
                return Recorder::fresh(path, scenario_name);
            }
            other => other?,
        };
        if back.name != scenario_name {
            tracing::warn!(path = %path.display(), recorded = %back.name, now = %scenario_name, "resuming a recording made with another scenario");
        }
        let mut file = OpenOptions::new().write(true).open(path).map_err(io(path))?;
        if back.tail.is_some() {
            tracing::warn!(path = %path.display(), tail = ?back.tail, "recording has a torn tail; truncating it");
            file.set_len(back.valid_len).map_err(io(path))?;
            file.sync_data().map_err(io(path))?;
        }
        file.seek(SeekFrom::Start(back.valid_len)).map_err(io(path))?;
        Ok((
            Recorder {
                file,
                path: path.into(),
                written: 0,
                bytes: back.valid_len,
            },
            back,
        ))
    }

    /// Open `path` for recording: resume it if it exists, else create it.
    ///
    /// # Errors
    /// As [`Recorder::create`] and [`Recorder::resume`].
    pub fn open(path: &Path, scenario_name: &str) -> Result<(Self, ReadBack), RecordingError> {
        if path.exists() {
            Recorder::resume(path, scenario_name)
        } else {
            Recorder::fresh(path, scenario_name)
        }
    }

    /// A new recording, with the (empty) read-back that resuming one would give.
    fn fresh(path: &Path, scenario_name: &str) -> Result<(Self, ReadBack), RecordingError> {
        let rec = Recorder::create(path, scenario_name)?;
        let back = ReadBack {
            name: scenario_name.into(),
            records: Vec::new(),
            valid_len: rec.bytes,
            tail: None,
        };
        Ok((rec, back))
    }

    /// Append one record with a single write.
    ///
    /// # Errors
    /// IO errors, and records whose envelope the wire encoding refuses.
    pub fn append(&mut self, record: &Stamped) -> Result<(), RecordingError> {
        let payload = record.encode().map_err(|source| RecordingError::Record {
            path: self.path.clone(),
            offset: self.bytes,
            source,
        })?;
        self.append_payload(&payload)
    }

    /// Append a raw payload (framing and CRC added here).
    ///
    /// # Errors
    /// IO errors.
    pub fn append_payload(&mut self, payload: &[u8]) -> Result<(), RecordingError> {
        let mut buf = Vec::with_capacity(payload.len() + 8);
        buf.extend_from_slice(&(payload.len() as u32).to_le_bytes());
        buf.extend_from_slice(&crc32fast::hash(payload).to_le_bytes());
        buf.extend_from_slice(payload);
        self.file.write_all(&buf).map_err(io(&self.path))?;
        self.written += 1;
        self.bytes += buf.len() as u64;
        Ok(())
    }

    /// Flush file data to the device (call on a timer and at shutdown).
    ///
    /// # Errors
    /// IO errors.
    pub fn sync(&mut self) -> Result<(), RecordingError> {
        self.file.sync_data().map_err(io(&self.path))
    }

    /// Records appended by this recorder.
    pub fn written(&self) -> u64 {
        self.written
    }

    /// Size of the file, bytes.
    pub fn bytes(&self) -> u64 {
        self.bytes
    }

    pub fn path(&self) -> &Path {
        &self.path
    }
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

#[cfg(test)]
mod tests {
    use super::*;
    use crate::decision::Decision;
    use crate::record::Record;
    use proto::{ClusterTime, NodeId};

    fn tmp(name: &str) -> PathBuf {
        let dir = std::env::temp_dir().join(format!("ocelli-rec-{}-{name}", std::process::id()));
        let _ = std::fs::remove_dir_all(&dir);
        std::fs::create_dir_all(&dir).unwrap();
        dir.join("rec.ocelli")
    }

    fn sample(n: i64) -> Vec<Stamped> {
        (0..n)
            .map(|i| {
                Stamped::new(
                    ClusterTime(i * 1000),
                    if i % 2 == 0 {
                        Record::Tick
                    } else {
                        Record::Decision(Decision::Up {
                            node: NodeId(i as u32),
                        })
                    },
                )
            })
            .collect()
    }

    fn write(path: &Path, recs: &[Stamped]) {
        let mut r = Recorder::create(path, "test").unwrap();
        for s in recs {
            r.append(s).unwrap();
        }
        r.sync().unwrap();
    }

    #[test]
    fn records_read_back_in_order() {
        let path = tmp("order");
        let recs = sample(5);
        write(&path, &recs);
        let back = read_all(&path).unwrap();
        assert_eq!(back.name, "test");
        assert_eq!(back.records, recs);
        assert_eq!(back.tail, None);
        assert_eq!(back.valid_len, std::fs::metadata(&path).unwrap().len());
    }

    #[test]
    fn truncation_at_every_offset_of_the_last_record_keeps_the_rest() {
        let path = tmp("trunc");
        let recs = sample(4);
        write(&path, &recs[..3]);
        let before = std::fs::metadata(&path).unwrap().len();
        let mut r = Recorder::resume(&path, "test").unwrap().0;
        r.append(&recs[3]).unwrap();
        let full = std::fs::read(&path).unwrap();
        for cut in before..full.len() as u64 {
            std::fs::write(&path, &full[..cut as usize]).unwrap();
            let back = read_all(&path).unwrap();
            assert_eq!(back.records, recs[..3], "cut at {cut}");
            if cut == before {
                assert_eq!(back.tail, None);
            } else {
                let tail = back.tail.expect("torn tail reported");
                assert_eq!(tail.offset, before);
                assert_eq!(tail.skipped_bytes, cut - before);
            }
        }
    }

    #[test]
    fn a_flipped_byte_is_caught_by_the_crc() {
        let path = tmp("flip");
        let recs = sample(3);
        write(&path, &recs);
        let full = std::fs::read(&path).unwrap();
        let last_start = {
            let mut rd = Reader::open(&path).unwrap();
            rd.next_payload().unwrap();
            rd.next_payload().unwrap();
            rd.valid_len()
        };
        let mut bad = full.clone();
        let i = full.len() - 2; // inside the last payload
        bad[i] ^= 0x10;
        std::fs::write(&path, &bad).unwrap();
        let back = read_all(&path).unwrap();
        assert_eq!(back.records, recs[..2]);
        let tail = back.tail.unwrap();
        assert_eq!(tail.problem, TailProblem::Checksum);
        assert_eq!(tail.offset, last_start);
    }

    #[test]
    fn resume_cuts_a_torn_tail_and_appends_after_it() {
        let path = tmp("resume");
        let recs = sample(3);
        write(&path, &recs);
        let full = std::fs::read(&path).unwrap();
        std::fs::write(&path, &full[..full.len() - 3]).unwrap();
        let (mut rec, back) = Recorder::resume(&path, "test").unwrap();
        assert_eq!(back.records, recs[..2]);
        assert!(back.tail.is_some());
        rec.append(&recs[2]).unwrap();
        let again = read_all(&path).unwrap();
        assert_eq!(again.records, recs);
        assert_eq!(again.tail, None);
    }

    #[test]
    fn not_a_recording_is_a_clear_error() {
        let path = tmp("magic");
        std::fs::write(&path, b"hello world, not a recording").unwrap();
        assert!(matches!(read_all(&path), Err(RecordingError::BadMagic { .. })));
        std::fs::write(&path, b"OCEL").unwrap();
        assert!(matches!(
            read_all(&path),
            Err(RecordingError::TruncatedHeader { .. })
        ));
        // A header-only torn file is restarted by `resume`.
        let (_, back) = Recorder::resume(&path, "fresh").unwrap();
        assert!(back.records.is_empty());
        assert_eq!(read_all(&path).unwrap().name, "fresh");
    }

    #[test]
    fn create_refuses_to_clobber() {
        let path = tmp("clobber");
        write(&path, &sample(1));
        assert!(matches!(
            Recorder::create(&path, "x"),
            Err(RecordingError::Io { .. })
        ));
    }

    proptest::proptest! {
        #![proptest_config(proptest::prelude::ProptestConfig::with_cases(64))]
        /// Cut anywhere after the header: exactly the records that fit whole read back.
        #[test]
        fn any_cut_reads_back_the_whole_records_before_it(n in 1i64..12, frac in 0.0f64..1.0) {
            let path = tmp(&format!("prop-{n}-{}", (frac * 1e6) as u64));
            let recs = sample(n);
            let mut r = Recorder::create(&path, "p").unwrap();
            let mut ends = Vec::new();
            for s in &recs {
                r.append(s).unwrap();
                ends.push(r.bytes());
            }
            let full = std::fs::read(&path).unwrap();
            let header = 12 + 1; // magic, version, name length, "p"
            let cut = header + ((full.len() as u64 - header) as f64 * frac) as u64;
            std::fs::write(&path, &full[..cut as usize]).unwrap();
            let back = read_all(&path).unwrap();
            let whole = ends.iter().filter(|e| **e <= cut).count();
            proptest::prop_assert_eq!(&back.records[..], &recs[..whole]);
            let _ = std::fs::remove_dir_all(path.parent().unwrap());
            proptest::prop_assert_eq!(back.tail.is_some(), cut != header && !ends.contains(&cut));
        }
    }
}
