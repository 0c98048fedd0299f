//! Following a recording while the server writes it: [`Tailer`] keeps its byte offset and, on
//! each [`Tailer::poll`], reads only the records appended since, in the framing of
//! [`crate::recording`].
//!
//! The server writes each record with one `write(2)`, so a reader racing it can see a record's
//! first bytes only. Such a record is *waited on*: the offset stays before it and the next poll
//! reads it again, complete by then. Damage is skipped as [`crate::recording::Reader`] skips
//! it, by scanning to the next valid record, and each skipped stretch is reported
//! ([`Tailer::skipped`]). The one difference is an incomplete-looking frame: a reader of a
//! whole file knows nothing follows, a tailer does not, so it waits unless a whole valid record
//! already follows in the bytes it has: a record still being written is always the last thing
//! in the file, so a frame with a valid record behind it is damage (a torn tail that a
//! restarted server appended after, or a length field hit by a flipped bit).

use crate::record::Stamped;
use crate::recording::{
    Damage, MAX_RECORD_BYTES, RecordingError, Skipped, Step, io, next_valid, note_skip, read_header, step,
};
use std::fs::File;
use std::io::{Read, Seek, SeekFrom};
use std::path::{Path, PathBuf};

/// Most bytes one poll reads: a long recording is taken in over several polls. More than a
/// whole frame of the largest record, so that any record can be judged.
const POLL_BYTES: u64 = 2 * MAX_RECORD_BYTES as u64;

/// An incremental reader of a growing recording.
#[derive(Debug)]
pub struct Tailer {
    path: PathBuf,
    file: Option<File>,
    /// File offset of `pending[0]`: where the next unread record starts (0 until the header
    /// has been read).
    offset: u64,
    /// Bytes read from `offset` on that are not consumed yet.
    pending: Vec<u8>,
    name: Option<String>,
    waiting: Option<Damage>,
    skipped: Vec<Skipped>,
}

impl Tailer {
    /// Follow the recording at `path`; the file need not exist yet.
    pub fn new(path: &Path) -> Self {
        Tailer {
            path: path.into(),
            file: None,
            offset: 0,
            pending: Vec::new(),
            name: None,
            waiting: None,
            skipped: Vec::new(),
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
    pub fn waiting_on(&self) -> Option<&Damage> {
        self.waiting.as_ref()
    }

    /// Every stretch skipped so far, in file order.
    pub fn skipped(&self) -> &[Skipped] {
        &self.skipped
    }

    /// Read the bytes appended since the last poll into `pending`.
    fn read_new(&mut self) -> Result<bool, RecordingError> {
        let path = self.path.clone();
        if self.file.is_none() {
            match File::open(&path) {
                Ok(f) => self.file = Some(f),
                Err(e) if e.kind() == std::io::ErrorKind::NotFound => return Ok(false),
                Err(e) => return Err(io(&path)(e)),
            }
        }
        let Some(file) = self.file.as_mut() else {
            return Ok(false);
        };
        let len = file.metadata().map_err(io(&path))?.len();
        let from = self.offset + self.pending.len() as u64;
        let to = len.min(from + POLL_BYTES);
        if to > from {
            file.seek(SeekFrom::Start(from)).map_err(io(&path))?;
            file.take(to - from)
                .read_to_end(&mut self.pending)
                .map_err(io(&path))?;
        }
        Ok(true)
    }

    /// The records appended since the last poll (at most [`POLL_BYTES`] of the file per
    /// poll); none while the file does not exist yet. Damage is skipped and added to
    /// [`Tailer::skipped`].
    ///
    /// # Errors
    /// IO errors, and a header with a wrong magic or version. The offset stays where it was,
    /// so nothing is lost by polling again.
    pub fn poll(&mut self) -> Result<Vec<Stamped>, RecordingError> {
        if !self.read_new()? {
            return Ok(Vec::new());
        }
        if self.name.is_none() {
            let Some((name, header_len)) = read_header(&mut &self.pending[..], &self.path)? else {
                return Ok(Vec::new());
            };
            self.name = Some(name);
            self.pending.drain(..header_len as usize);
            self.offset = header_len;
        }
        let mut out = Vec::new();
        let mut at = 0;
        self.waiting = None;
        loop {
            let window = &self.pending[at..];
            let here = self.offset + at as u64;
            match step(window, false) {
                Step::End => break,
                Step::Record { record, frame_len } => {
                    out.push(record);
                    at += frame_len;
                }
                Step::Skip { bytes, damage } => {
                    note_skip(&mut self.skipped, here, bytes as u64, damage);
                    at += bytes;
                }
                Step::NeedMore { damage, .. } => match next_valid(window, 1) {
                    Some(valid) => {
                        note_skip(&mut self.skipped, here, valid as u64, damage);
                        at += valid;
                    }
                    None => {
                        if !window.is_empty() {
                            self.waiting = Some(damage);
                        }
                        break;
                    }
                },
            }
        }
        self.pending.drain(..at);
        self.offset += at as u64;
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
            (3, Damage::ShortHeader),
            (
                one.len() - 1,
                Damage::ShortPayload {
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
        assert_eq!(tail.waiting_on(), Some(&Damage::ShortHeader));
        append_raw(&path, &two[4..]);
        assert_eq!(tail.poll().unwrap(), vec![record(2)]);
        assert_eq!(tail.waiting_on(), None);
        // The server writes on after a restart.
        let (mut rec, back) = Recorder::resume(&path, "tail-test").unwrap();
        assert_eq!(back.records.len(), 2);
        rec.append(&record(3)).unwrap();
        assert_eq!(tail.poll().unwrap(), vec![record(3)]);
        let _ = std::fs::remove_dir_all(path.parent().unwrap());
    }

    /// A bit flipped in a record the tailer has not read yet: that record is skipped and
    /// reported, the ones around it are read, and following goes on.
    #[test]
    fn mid_file_damage_is_skipped_and_reported() {
        let path = scratch("flip");
        let mut rec = Recorder::create(&path, "tail-test").unwrap();
        let start = rec.bytes();
        for k in 1..=3 {
            rec.append(&record(k)).unwrap();
        }
        let mut bytes = std::fs::read(&path).unwrap();
        let frame = framed(&record(2)).len() as u64;
        let second = start + frame;
        bytes[second as usize + 9] ^= 0x01;
        std::fs::write(&path, &bytes).unwrap();
        let mut tail = Tailer::new(&path);
        assert_eq!(tail.poll().unwrap(), vec![record(1), record(3)]);
        assert_eq!(
            tail.skipped(),
            [Skipped {
                offset: second,
                bytes: frame,
                damage: Damage::Checksum
            }]
        );
        rec.append(&record(4)).unwrap();
        assert_eq!(tail.poll().unwrap(), vec![record(4)]);
        assert_eq!(tail.skipped().len(), 1);
        let _ = std::fs::remove_dir_all(path.parent().unwrap());
    }

    /// A crash left a torn record (cut in its payload, or in its frame header); the restarted
    /// server appends after it. The tailer first waits on the torn bytes (they could be a record
    /// still being written), then skips them once a valid record follows.
    #[test]
    fn a_torn_tail_is_skipped_once_a_restarted_server_appends_after_it() {
        for keep in [3, 12] {
            let path = scratch(&format!("resumed-{keep}"));
            let mut rec = Recorder::create(&path, "tail-test").unwrap();
            rec.append(&record(1)).unwrap();
            let torn_at = rec.bytes();
            drop(rec);
            append_raw(&path, &framed(&record(2))[..keep]);
            let mut tail = Tailer::new(&path);
            assert_eq!(tail.poll().unwrap(), vec![record(1)]);
            assert!(tail.waiting_on().is_some(), "keep {keep}");
            assert_eq!(tail.skipped(), []);
            let (mut rec, back) = Recorder::resume(&path, "tail-test").unwrap();
            assert_eq!(back.records, vec![record(1)]);
            rec.append(&record(3)).unwrap();
            rec.append(&record(4)).unwrap();
            assert_eq!(tail.poll().unwrap(), vec![record(3), record(4)], "keep {keep}");
            assert_eq!(tail.skipped().len(), 1);
            assert_eq!(tail.skipped()[0].offset, torn_at);
            assert_eq!(tail.skipped()[0].bytes, keep as u64);
            assert_eq!(tail.waiting_on(), None);
            let _ = std::fs::remove_dir_all(path.parent().unwrap());
        }
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
