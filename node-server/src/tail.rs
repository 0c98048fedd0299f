//! Following a recording while the server writes it: [`Tailer`] keeps its byte offset and, on
//! each [`Tailer::poll`], reads only the records appended since, in the framing of
//! [`crate::recording`].
//!
//! The server writes each record with one `write(2)`, so a reader racing it can see a record's
//! first bytes only. Such a tail is *waited on*: the offset stays before it and the next poll
//! reads it again, complete by then. Unlike [`crate::recording::Reader`], which skips a torn
//! tail (the writer is gone), a tailer never skips anything. A restarted server truncates a
//! torn tail and appends from there, which is where the tailer waits. A record that is complete
//! and checksummed but does not decode is an error (it was written by another build).

use crate::record::Stamped;
use crate::recording::{MAX_RECORD_BYTES, RecordingError, TailProblem, io, read_full, read_header};
use std::fs::File;
use std::io::{BufReader, Read, Seek, SeekFrom};
use std::path::{Path, PathBuf};

/// An incremental reader of a growing recording.
#[derive(Debug)]
pub struct Tailer {
    path: PathBuf,
    file: Option<File>,
    /// Where the next unread record starts (0 until the header has been read).
    offset: u64,
    name: Option<String>,
    waiting: Option<TailProblem>,
}

impl Tailer {
    /// Follow the recording at `path`; the file need not exist yet.
    pub fn new(path: &Path) -> Self {
        Tailer {
            path: path.into(),
            file: None,
            offset: 0,
            name: None,
            waiting: None,
        }
    }

    /// Byte offset of the first record not read yet.
    pub fn offset(&self) -> u64 {
        self.offset
    }

    /// The scenario name, once the header has been read.
    pub fn name(&self) -> Option<&str> {
        self.name.as_deref()
    }

    /// What the last poll found after the last whole record (an incomplete record it waits on).
    pub fn waiting_on(&self) -> Option<&TailProblem> {
        self.waiting.as_ref()
    }

    /// The records appended since the last poll; none while the file does not exist yet.
    ///
    /// # Errors
    /// IO errors, a header with a wrong magic or version, a record that does not decode. The
    /// offset stays where it was, so nothing is lost by polling again.
    pub fn poll(&mut self) -> Result<Vec<Stamped>, RecordingError> {
        let path = self.path.clone();
        if self.file.is_none() {
            match File::open(&path) {
                Ok(f) => self.file = Some(f),
                Err(e) if e.kind() == std::io::ErrorKind::NotFound => return Ok(Vec::new()),
                Err(e) => return Err(io(&path)(e)),
            }
        }
        let Some(file) = self.file.as_mut() else {
            return Ok(Vec::new());
        };
        let len = file.metadata().map_err(io(&path))?.len();
        file.seek(SeekFrom::Start(self.offset)).map_err(io(&path))?;
        let mut input = BufReader::new(file.take(len.saturating_sub(self.offset)));
        if self.name.is_none() {
            match read_header(&mut input, &path)? {
                Some((name, header_len)) => {
                    self.name = Some(name);
                    self.offset = header_len;
                }
                None => return Ok(Vec::new()),
            }
        }
        let mut out = Vec::new();
        self.waiting = None;
        loop {
            let mut head = [0u8; 8];
            if !read_full(&mut input, &mut head).map_err(io(&path))? {
                if self.offset < len {
                    self.waiting = Some(TailProblem::ShortHeader);
                }
                break;
            }
            let rlen = u32::from_le_bytes([head[0], head[1], head[2], head[3]]);
            let crc = u32::from_le_bytes([head[4], head[5], head[6], head[7]]);
            if rlen == 0 || rlen > MAX_RECORD_BYTES {
                self.waiting = Some(TailProblem::BadLength { len: rlen });
                break;
            }
            let mut payload = vec![0u8; rlen as usize];
            if !read_full(&mut input, &mut payload).map_err(io(&path))? {
                self.waiting = Some(TailProblem::ShortPayload { len: rlen });
                break;
            }
            if crc32fast::hash(&payload) != crc {
                self.waiting = Some(TailProblem::Checksum);
                break;
            }
            let record = Stamped::decode(&payload).map_err(|source| RecordingError::Record {
                path: path.clone(),
                offset: self.offset,
                source,
            })?;
            out.push(record);
            self.offset += 8 + u64::from(rlen);
        }
        Ok(out)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::record::Record;
    use crate::recording::Recorder;
    use proto::ClusterTime;
    use std::io::Write;

    fn record(k: i64) -> Stamped {
        Stamped::new(ClusterTime(k), Record::Tick)
    }

    fn scratch(name: &str) -> PathBuf {
        let dir = std::env::temp_dir().join(format!("ocelli-tail-{name}-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&dir);
        std::fs::create_dir_all(&dir).unwrap();
        dir.join("rec.ocrec")
    }

    fn append_raw(path: &Path, bytes: &[u8]) {
        let mut f = std::fs::OpenOptions::new().append(true).open(path).unwrap();
        f.write_all(bytes).unwrap();
    }

    fn framed(s: &Stamped) -> Vec<u8> {
        let payload = s.encode().unwrap();
        let mut out = (payload.len() as u32).to_le_bytes().to_vec();
        out.extend_from_slice(&crc32fast::hash(&payload).to_le_bytes());
        out.extend_from_slice(&payload);
        out
    }

    #[test]
    fn reads_only_what_was_appended_since_the_last_poll() {
        let path = scratch("incremental");
        let mut tail = Tailer::new(&path);
        assert!(tail.poll().unwrap().is_empty(), "no file yet");
        let mut rec = Recorder::create(&path, "tail-test").unwrap();
        rec.append(&record(1)).unwrap();
        rec.append(&record(2)).unwrap();
        assert_eq!(tail.poll().unwrap(), vec![record(1), record(2)]);
        assert_eq!(tail.name(), Some("tail-test"));
        assert!(tail.poll().unwrap().is_empty());
        rec.append(&record(3)).unwrap();
        assert_eq!(tail.poll().unwrap(), vec![record(3)]);
        assert_eq!(tail.offset(), std::fs::metadata(&path).unwrap().len());
        assert_eq!(tail.waiting_on(), None);
        let _ = std::fs::remove_dir_all(path.parent().unwrap());
    }

    /// A record whose bytes arrive in pieces is waited on, not skipped, and read whole once
    /// complete; so is a header written in pieces.
    #[test]
    fn a_torn_tail_is_waited_on_while_the_file_grows() {
        let path = scratch("torn");
        drop(Recorder::create(&path, "tail-test").unwrap());
        let header = std::fs::read(&path).unwrap();
        std::fs::write(&path, &header[..5]).unwrap();
        let mut tail = Tailer::new(&path);
        assert!(tail.poll().unwrap().is_empty(), "half a header");
        append_raw(&path, &header[5..]);
        assert!(tail.poll().unwrap().is_empty());
        let start = tail.offset();
        assert_eq!(start, header.len() as u64);
        let (one, two) = (framed(&record(1)), framed(&record(2)));
        // Inside the frame header, then inside the payload.
        for (cut, problem) in [
            (3, TailProblem::ShortHeader),
            (
                one.len() - 1,
                TailProblem::ShortPayload {
                    len: one.len() as u32 - 8,
                },
            ),
        ] {
            std::fs::write(&path, [&header[..], &one[..cut]].concat()).unwrap();
            assert!(tail.poll().unwrap().is_empty(), "cut at {cut}");
            assert_eq!(tail.offset(), start, "nothing consumed");
            assert_eq!(tail.waiting_on(), Some(&problem));
        }
        append_raw(&path, &one[one.len() - 1..]);
        append_raw(&path, &two[..4]);
        assert_eq!(tail.poll().unwrap(), vec![record(1)]);
        assert_eq!(tail.waiting_on(), Some(&TailProblem::ShortHeader));
        append_raw(&path, &two[4..]);
        assert_eq!(tail.poll().unwrap(), vec![record(2)]);
        assert_eq!(tail.waiting_on(), None);
        // The server writes on after a restart (it truncates any torn tail first).
        let (mut rec, back) = Recorder::resume(&path, "tail-test").unwrap();
        assert_eq!(back.records.len(), 2);
        rec.append(&record(3)).unwrap();
        assert_eq!(tail.poll().unwrap(), vec![record(3)]);
        let _ = std::fs::remove_dir_all(path.parent().unwrap());
    }

    #[test]
    fn a_file_that_is_not_a_recording_is_an_error() {
        let path = scratch("magic");
        std::fs::write(&path, b"NOTOCELLI-----").unwrap();
        assert!(matches!(
            Tailer::new(&path).poll(),
            Err(RecordingError::BadMagic { .. })
        ));
        let _ = std::fs::remove_dir_all(path.parent().unwrap());
    }
}
