//! The append side of a recording: create or resume a file under an exclusive lock, and append
//! records to it, each with one `write(2)` on an `O_APPEND` descriptor.

use super::{
    FILE_MODE, FRAME_HEADER, MAX_RECORD_BYTES, ReadBack, Reader, RecordingError, header_bytes, io, read_back,
};
use crate::record::Stamped;
use std::fs::{File, OpenOptions, TryLockError};
use std::io::{BufReader, Read, Seek, SeekFrom, Write};
use std::path::{Path, PathBuf};

/// The append side of a recording. Holds the file's exclusive lock while it lives.
#[derive(Debug)]
pub struct Recorder {
    file: File,
    path: PathBuf,
    written: u64,
    bytes: u64,
}

/// Open `path` for reading and appending (creating it, `0640`, when `create`) and take its
/// exclusive lock.
fn open_locked(path: &Path, create: bool) -> Result<File, RecordingError> {
    let mut options = OpenOptions::new();
    options.read(true).append(true);
    if create {
        options.create_new(true);
        #[cfg(unix)]
        std::os::unix::fs::OpenOptionsExt::mode(&mut options, FILE_MODE);
    }
    let file = options.open(path).map_err(io(path))?;
    match file.try_lock() {
        Ok(()) => Ok(file),
        Err(TryLockError::WouldBlock) => Err(RecordingError::InUse { path: path.into() }),
        Err(TryLockError::Error(e)) => Err(io(path)(e)),
    }
}

/// The first free `<path>.damaged-<n>`.
fn aside_path(path: &Path) -> PathBuf {
    let mut n = 1u32;
    loop {
        let mut name = path.as_os_str().to_owned();
        name.push(format!(".damaged-{n}"));
        let candidate = PathBuf::from(name);
        if !candidate.exists() {
            return candidate;
        }
        n += 1;
    }
}

impl Recorder {
    /// Create a new recording (fails if the file exists).
    ///
    /// # Errors
    /// IO errors (including an existing file), an over-long name, and a file another process
    /// locked first.
    pub fn create(path: &Path, scenario_name: &str) -> Result<Self, RecordingError> {
        let header = header_bytes(scenario_name)?;
        let mut file = open_locked(path, true)?;
        file.write_all(&header).map_err(io(path))?;
        file.sync_data().map_err(io(path))?;
        Ok(Recorder {
            file,
            path: path.into(),
            written: 0,
            bytes: header.len() as u64,
        })
    }

    /// Reopen an existing recording: lock it, read it back (skipping damage, which stays in
    /// the file), and append after its last byte. A file too short to hold its header gets the
    /// rest of this server's header if its bytes begin it; otherwise it is renamed aside
    /// (`<file>.damaged-<n>`) and a new recording started.
    ///
    /// # Errors
    /// IO errors, a file that is not a recording or has another format version, and a file
    /// another process holds ([`RecordingError::InUse`]).
    pub fn resume(path: &Path, scenario_name: &str) -> Result<(Self, ReadBack), RecordingError> {
        let header = header_bytes(scenario_name)?;
        let mut file = open_locked(path, false)?;
        let len = file.metadata().map_err(io(path))?.len();
        let back = match Reader::new(BufReader::new(&file), len, path) {
            Ok(reader) => read_back(reader)?,
            Err(RecordingError::TruncatedHeader { .. }) => {
                let mut have = Vec::new();
                (&file).seek(SeekFrom::Start(0)).map_err(io(path))?;
                (&file).read_to_end(&mut have).map_err(io(path))?;
                if !header.starts_with(&have) {
                    let aside = aside_path(path);
                    tracing::warn!(path = %path.display(), aside = %aside.display(), bytes = have.len(), "recording has a torn header that is not ours; renamed aside");
                    std::fs::rename(path, &aside).map_err(io(path))?;
                    drop(file);
                    return Recorder::fresh(path, scenario_name);
                }
                tracing::warn!(path = %path.display(), bytes = have.len(), "recording has a torn header; completing it");
                file.write_all(&header[have.len()..]).map_err(io(path))?;
                file.sync_data().map_err(io(path))?;
                ReadBack {
                    name: scenario_name.into(),
                    records: Vec::new(),
                    skipped: Vec::new(),
                    len: header.len() as u64,
                }
            }
            Err(e) => return Err(e),
        };
        if back.name != scenario_name {
            tracing::warn!(path = %path.display(), recorded = %back.name, now = %scenario_name, "resuming a recording made with another scenario");
        }
        for s in &back.skipped {
            tracing::warn!(path = %path.display(), offset = s.offset, bytes = s.bytes, damage = ?s.damage, "recording: damaged stretch skipped (kept in the file)");
        }
        Ok((
            Recorder {
                file,
                path: path.into(),
                written: 0,
                bytes: back.len,
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
            return Recorder::resume(path, scenario_name);
        }
        match Recorder::fresh(path, scenario_name) {
            // Another process created it in between: resume (its lock decides who records).
            Err(RecordingError::Io { source, .. }) if source.kind() == std::io::ErrorKind::AlreadyExists => {
                Recorder::resume(path, scenario_name)
            }
            other => other,
        }
    }

    /// A new recording, with the (empty) read-back that resuming one would give.
    fn fresh(path: &Path, scenario_name: &str) -> Result<(Self, ReadBack), RecordingError> {
        let rec = Recorder::create(path, scenario_name)?;
        let back = ReadBack {
            name: scenario_name.into(),
            records: Vec::new(),
            skipped: Vec::new(),
            len: rec.bytes,
        };
        Ok((rec, back))
    }

    /// Append one record with a single write.
    ///
    /// # Errors
    /// IO errors, records whose envelope the wire encoding refuses, and records over
    /// [`MAX_RECORD_BYTES`] ([`RecordingError::RecordSize`]).
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
    /// IO errors, and an empty payload or one over [`MAX_RECORD_BYTES`] (no reader would
    /// take it); nothing is written then.
    pub fn append_payload(&mut self, payload: &[u8]) -> Result<(), RecordingError> {
        let len = u32::try_from(payload.len())
            .ok()
            .filter(|n| (1..=MAX_RECORD_BYTES).contains(n))
            .ok_or_else(|| RecordingError::RecordSize {
                path: self.path.clone(),
                bytes: payload.len(),
            })?;
        let mut buf = Vec::with_capacity(payload.len() + FRAME_HEADER);
        buf.extend_from_slice(&len.to_le_bytes());
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
