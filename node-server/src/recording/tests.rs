//! Tests of the recording file: read-back, damage skipped and reported, resume without losing a
//! byte, the lock, the file mode, and random damage.

use super::*;
use crate::decision::Decision;
use crate::record::Record;
use proptest::prelude::*;
use proto::{ClusterTime, NodeId};

/// A recording's path in a scratch folder of its own, removed when the folder is dropped.
fn tmp(name: &str) -> (tempfile::TempDir, PathBuf) {
    let dir = tempfile::Builder::new()
        .prefix(&format!("ocelli-rec-{name}-"))
        .tempdir()
        .unwrap();
    let path = dir.path().join("rec.ocelli");
    (dir, path)
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

/// Write `recs` to a new recording named "test"; the byte range of each record's frame.
fn write(path: &Path, recs: &[Stamped]) -> Vec<std::ops::Range<u64>> {
    let mut r = Recorder::create(path, "test").unwrap();
    let mut frames = Vec::new();
    for s in recs {
        let start = r.bytes();
        r.append(s).unwrap();
        frames.push(start..r.bytes());
    }
    r.sync().unwrap();
    frames
}

const HEADER: u64 = 12 + 4; // magic, version, name length, "test"

#[test]
fn records_read_back_in_order() {
    let (_dir, path) = tmp("order");
    let recs = sample(5);
    write(&path, &recs);
    let back = read_all(&path).unwrap();
    assert_eq!(back.name, "test");
    assert_eq!(back.records, recs);
    assert_eq!(back.skipped, []);
    assert_eq!(back.len, std::fs::metadata(&path).unwrap().len());
}

#[test]
fn truncation_at_every_offset_of_the_last_record_keeps_the_rest() {
    let (_dir, path) = tmp("trunc");
    let recs = sample(4);
    let frames = write(&path, &recs);
    let full = std::fs::read(&path).unwrap();
    let before = frames[3].start;
    for cut in before..full.len() as u64 {
        let back = read_bytes(&full[..cut as usize], &path).unwrap();
        assert_eq!(back.records, recs[..3], "cut at {cut}");
        if cut == before {
            assert_eq!(back.skipped, []);
        } else {
            assert_eq!(back.skipped.len(), 1, "cut at {cut}");
            assert_eq!(back.skipped[0].offset, before);
            assert_eq!(back.skipped[0].bytes, cut - before);
        }
    }
}

/// The probe: one flipped bit at 28% of a file. The reader returns every record but the
/// damaged one and reports exactly that record's bytes as skipped.
#[test]
fn a_flipped_bit_at_28_percent_loses_only_its_record() {
    let (_dir, path) = tmp("flip28");
    let recs = sample(50);
    let frames = write(&path, &recs);
    let mut bytes = std::fs::read(&path).unwrap();
    let at = bytes.len() * 28 / 100;
    bytes[at] ^= 0x04;
    std::fs::write(&path, &bytes).unwrap();
    let hit = frames.iter().position(|f| f.contains(&(at as u64))).unwrap();
    let back = read_all(&path).unwrap();
    let mut expected = recs.clone();
    expected.remove(hit);
    assert_eq!(back.records, expected);
    assert_eq!(
        back.skipped
            .iter()
            .map(|s| (s.offset, s.bytes))
            .collect::<Vec<_>>(),
        [(frames[hit].start, frames[hit].end - frames[hit].start)]
    );
}

/// A restarted server resumes a file damaged in the middle: it appends after the last byte,
/// nothing before or after the damage is lost, and the damaged bytes stay where they were.
#[test]
fn resume_after_mid_file_damage_appends_and_loses_nothing_else() {
    let (_dir, path) = tmp("resume-mid");
    let recs = sample(20);
    let frames = write(&path, &recs[..10]);
    let mut bytes = std::fs::read(&path).unwrap();
    let at = (frames[3].start + 10) as usize;
    bytes[at] ^= 0x80;
    std::fs::write(&path, &bytes).unwrap();
    let (mut rec, back) = Recorder::resume(&path, "test").unwrap();
    let mut expected: Vec<_> = recs[..10].to_vec();
    expected.remove(3);
    assert_eq!(back.records, expected);
    assert_eq!(back.skipped_bytes(), frames[3].end - frames[3].start);
    for s in &recs[10..] {
        rec.append(s).unwrap();
    }
    drop(rec);
    let after = std::fs::read(&path).unwrap();
    assert_eq!(
        after[..bytes.len()],
        bytes[..],
        "no byte before the resume changed"
    );
    let again = read_all(&path).unwrap();
    expected.extend_from_slice(&recs[10..]);
    assert_eq!(again.records, expected);
    assert_eq!(again.skipped, back.skipped);
}

/// A torn tail is kept in place: resume appends after it, every reader skips and reports it,
/// and the records on both sides read back.
#[test]
fn a_torn_tail_is_kept_and_skipped_after_resume() {
    let (_dir, path) = tmp("resume-torn");
    let recs = sample(6);
    let frames = write(&path, &recs[..3]);
    let full = std::fs::read(&path).unwrap();
    let torn = &full[..full.len() - 3];
    std::fs::write(&path, torn).unwrap();
    let (mut rec, back) = Recorder::resume(&path, "test").unwrap();
    assert_eq!(back.records, recs[..2]);
    let tail = Skipped {
        offset: frames[2].start,
        bytes: frames[2].end - frames[2].start - 3,
        damage: Damage::ShortPayload {
            len: (frames[2].end - frames[2].start - 8) as u32,
        },
    };
    assert_eq!(back.skipped, [tail]);
    for s in &recs[3..] {
        rec.append(s).unwrap();
    }
    let after = std::fs::read(&path).unwrap();
    assert_eq!(
        after[..torn.len()],
        torn[..],
        "the torn tail is still in the file"
    );
    let again = read_all(&path).unwrap();
    assert_eq!(again.records, [&recs[..2], &recs[3..]].concat());
    assert_eq!(again.skipped.len(), 1);
    assert_eq!(again.skipped[0].offset, tail.offset);
    assert_eq!(again.skipped[0].bytes, tail.bytes);
}

#[test]
fn a_second_recorder_on_the_same_file_is_refused() {
    let (_dir, path) = tmp("lock");
    let first = Recorder::create(&path, "test").unwrap();
    let err = Recorder::open(&path, "test").unwrap_err();
    assert!(
        matches!(&err, RecordingError::InUse { path: p } if *p == path),
        "{err:?}"
    );
    let msg = err.to_string();
    assert!(
        msg.contains(&path.display().to_string()) && msg.contains("in use"),
        "{msg}"
    );
    assert!(matches!(
        Recorder::resume(&path, "test"),
        Err(RecordingError::InUse { .. })
    ));
    drop(first);
    let (_, back) = Recorder::open(&path, "test").unwrap();
    assert!(back.records.is_empty());
}

/// The process umask, from `/proc/self/status` (Linux).
fn umask() -> u32 {
    let status = std::fs::read_to_string("/proc/self/status").unwrap();
    let line = status.lines().find(|l| l.starts_with("Umask:")).unwrap();
    u32::from_str_radix(line["Umask:".len()..].trim(), 8).unwrap()
}

#[cfg(unix)]
#[test]
fn a_new_recording_is_not_world_readable() {
    use std::os::unix::fs::PermissionsExt;
    let (_dir, path) = tmp("mode");
    drop(Recorder::create(&path, "test").unwrap());
    let mode = std::fs::metadata(&path).unwrap().permissions().mode() & 0o777;
    assert_eq!(mode, FILE_MODE & !umask());
    assert_eq!(mode & 0o007, 0, "no access for others");
}

#[test]
fn an_oversized_payload_is_refused_and_writes_nothing() {
    let (_dir, path) = tmp("oversized");
    let mut rec = Recorder::create(&path, "test").unwrap();
    let before = std::fs::read(&path).unwrap();
    let big = vec![0u8; MAX_RECORD_BYTES as usize + 1];
    assert!(matches!(
        rec.append_payload(&big),
        Err(RecordingError::RecordSize { bytes, .. }) if bytes == big.len()
    ));
    assert!(matches!(
        rec.append_payload(&[]),
        Err(RecordingError::RecordSize { bytes: 0, .. })
    ));
    assert_eq!(std::fs::read(&path).unwrap(), before);
    assert_eq!(rec.bytes(), before.len() as u64);
}

#[test]
fn not_a_recording_is_a_clear_error() {
    let (_dir, path) = tmp("magic");
    std::fs::write(&path, b"hello world, not a recording").unwrap();
    assert!(matches!(read_all(&path), Err(RecordingError::BadMagic { .. })));
    assert!(matches!(
        Recorder::open(&path, "x"),
        Err(RecordingError::BadMagic { .. })
    ));
    assert_eq!(std::fs::read(&path).unwrap(), b"hello world, not a recording");
}

/// A header cut short is completed when it is the start of ours ...
#[test]
fn a_torn_header_of_ours_is_completed() {
    let (_dir, path) = tmp("torn-header");
    std::fs::write(&path, b"OCEL").unwrap();
    assert!(matches!(
        read_all(&path),
        Err(RecordingError::TruncatedHeader { .. })
    ));
    let (mut rec, back) = Recorder::resume(&path, "fresh").unwrap();
    assert!(back.records.is_empty());
    rec.append(&sample(1)[0]).unwrap();
    let again = read_all(&path).unwrap();
    assert_eq!(again.name, "fresh");
    assert_eq!(again.records, sample(1));
}

/// ... and renamed aside, untouched, when it is not.
#[test]
fn a_torn_header_not_ours_is_moved_aside() {
    let (_dir, path) = tmp("torn-other");
    let torn = [
        &MAGIC[..],
        &FORMAT_VERSION.to_le_bytes(),
        &5u16.to_le_bytes(),
        b"ot",
    ]
    .concat();
    std::fs::write(&path, &torn).unwrap();
    let (_, back) = Recorder::open(&path, "mine").unwrap();
    assert!(back.records.is_empty());
    let mut aside = path.as_os_str().to_owned();
    aside.push(".damaged-1");
    assert_eq!(std::fs::read(PathBuf::from(aside)).unwrap(), torn);
    assert_eq!(read_all(&path).unwrap().name, "mine");
}

#[test]
fn create_refuses_to_clobber() {
    let (_dir, path) = tmp("clobber");
    write(&path, &sample(1));
    assert!(matches!(
        Recorder::create(&path, "x"),
        Err(RecordingError::Io { .. })
    ));
}

/// A file larger than one read-ahead with damage across a read-ahead boundary.
#[test]
fn damage_across_the_read_ahead_is_skipped() {
    let (_dir, path) = tmp("big");
    let recs = sample(12_000);
    let frames = write(&path, &recs);
    let mut bytes = std::fs::read(&path).unwrap();
    assert!(bytes.len() > 2 * READ_AHEAD);
    // Zero 40 bytes around the first read-ahead boundary.
    let from = READ_AHEAD - 20;
    bytes[from..from + 40].fill(0);
    std::fs::write(&path, &bytes).unwrap();
    let back = read_all(&path).unwrap();
    let hit = |f: &std::ops::Range<u64>| f.start < (from + 40) as u64 && f.end > from as u64;
    let expected: Vec<_> = recs
        .iter()
        .zip(&frames)
        .filter(|(_, f)| !hit(f))
        .map(|(r, _)| r.clone())
        .collect();
    assert_eq!(back.records, expected);
    assert_eq!(back.skipped.len(), 1);
    let first_hit = frames.iter().find(|f| hit(f)).unwrap();
    assert_eq!(back.skipped[0].offset, first_hit.start);
}

/// One edit of a recording, at a position in the original bytes.
#[derive(Clone, Debug)]
enum Edit {
    Flip { at: usize, bit: u8 },
    Insert { at: usize, bytes: Vec<u8> },
    Delete { at: usize, len: usize },
}

impl Edit {
    fn at(&self) -> usize {
        match self {
            Edit::Flip { at, .. } | Edit::Insert { at, .. } | Edit::Delete { at, .. } => *at,
        }
    }

    /// Whether this edit changes the bytes of the frame at `f`.
    fn touches(&self, f: &std::ops::Range<u64>) -> bool {
        let (s, e) = (f.start as usize, f.end as usize);
        match self {
            Edit::Flip { at, .. } => (s..e).contains(at),
            Edit::Insert { at, .. } => s < *at && *at < e,
            Edit::Delete { at, len } => *at < e && at + len > s,
        }
    }

    /// The original bytes this edit works on (an insertion counts the byte after it).
    fn end(&self) -> usize {
        match self {
            Edit::Flip { at, .. } | Edit::Insert { at, .. } => at + 1,
            Edit::Delete { at, len } => at + len,
        }
    }

    fn apply(&self, bytes: &mut Vec<u8>) {
        match self {
            Edit::Flip { at, bit } => bytes[*at] ^= 1 << bit,
            Edit::Insert { at, bytes: ins } => {
                bytes.splice(*at..*at, ins.iter().copied());
            }
            Edit::Delete { at, len } => {
                bytes.drain(*at..at + len);
            }
        }
    }
}

fn edit(len: usize) -> impl Strategy<Value = Edit> {
    prop_oneof![
        (0..len, 0u8..8).prop_map(|(at, bit)| Edit::Flip { at, bit }),
        (0..=len, proptest::collection::vec(any::<u8>(), 1..40))
            .prop_map(|(at, bytes)| Edit::Insert { at, bytes }),
        (0..len, 1usize..40).prop_map(|(at, len)| Edit::Delete { at, len }),
    ]
}

const PROP_RECORDS: i64 = 24;

/// Whether `small` appears in `big` in order (not necessarily contiguously).
fn is_subsequence(small: &[Stamped], big: &[Stamped]) -> bool {
    let mut big = big.iter();
    small.iter().all(|s| big.any(|b| b == s))
}

/// The bytes and frames of a fixed recording, made once.
fn prop_file() -> &'static (Vec<u8>, Vec<std::ops::Range<u64>>) {
    static FILE: std::sync::OnceLock<(Vec<u8>, Vec<std::ops::Range<u64>>)> = std::sync::OnceLock::new();
    FILE.get_or_init(|| {
        let (_dir, path) = tmp("prop-source");
        let frames = write(&path, &sample(PROP_RECORDS));
        let bytes = std::fs::read(&path).unwrap();
        (bytes, frames)
    })
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(256))]
    /// Random flips, insertions and deletions after the header: reading never panics, every
    /// record whose frame no edit touched reads back, no record that was not written appears
    /// (what reads back is a subsequence of what was written: an edit that happens to leave a
    /// frame's bytes as they were may keep it), and every byte is either header, a record
    /// read, or reported as skipped.
    #[test]
    fn random_damage_yields_exactly_the_untouched_records(
        edits in proptest::collection::vec(edit(4000), 1..4),
    ) {
        let (original, frames) = prop_file();
        let recs = sample(PROP_RECORDS);
        let body = original.len() - HEADER as usize;
        let mut edits: Vec<Edit> = edits
            .into_iter()
            .map(|e| match e {
                Edit::Flip { at, bit } => Edit::Flip { at: HEADER as usize + at % body, bit },
                Edit::Insert { at, bytes } => Edit::Insert { at: HEADER as usize + at % (body + 1), bytes },
                Edit::Delete { at, len } => {
                    let at = HEADER as usize + at % body;
                    Edit::Delete { at, len: len.min(original.len() - at) }
                }
            })
            .collect();
        // Keep edits that do not overlap, and apply them from the back so that each position
        // still refers to the original bytes.
        edits.sort_by_key(Edit::at);
        let mut kept: Vec<Edit> = Vec::new();
        for e in edits {
            if kept.last().is_none_or(|k| e.at() >= k.end()) {
                kept.push(e);
            }
        }
        let edits: Vec<Edit> = kept.into_iter().rev().collect();
        let mut bytes = original.clone();
        for e in &edits {
            e.apply(&mut bytes);
        }
        let untouched: Vec<_> = recs
            .iter()
            .zip(frames)
            .filter(|(_, f)| !edits.iter().any(|e| e.touches(f)))
            .map(|(r, _)| r.clone())
            .collect();
        let back = read_bytes(&bytes, Path::new("<prop>")).unwrap();
        prop_assert!(is_subsequence(&untouched, &back.records), "lost an untouched record: {:?}", back.skipped);
        prop_assert!(is_subsequence(&back.records, &recs), "a record that was not written");
        let record_bytes: u64 = back.records.iter().map(|r| 8 + r.encode().unwrap().len() as u64).sum();
        prop_assert_eq!(HEADER + record_bytes + back.skipped_bytes(), bytes.len() as u64);
    }

    /// Arbitrary bytes after a valid header never panic and yield only records that decode.
    #[test]
    fn arbitrary_bytes_after_a_header_never_panic(tail in proptest::collection::vec(any::<u8>(), 0..2000)) {
        let mut bytes = header_bytes("test").unwrap();
        bytes.extend_from_slice(&tail);
        let back = read_bytes(&bytes, Path::new("<prop>")).unwrap();
        let record_bytes: u64 = back.records.iter().map(|r| 8 + r.encode().unwrap().len() as u64).sum();
        prop_assert_eq!(HEADER + record_bytes + back.skipped_bytes(), bytes.len() as u64);
    }
}

/// The server's start on a damaged recording: it resumes, records how many bytes it skipped in
/// its `Resumed` decision, and keeps every record on both sides of the damage.
#[test]
fn the_server_resumes_a_damaged_recording_and_records_the_skip() {
    let (_dir, path) = tmp("server-start");
    let scenario = crate::testkit::scenario();
    let id = NodeId(1);
    let cfg = crate::process::ProcessConfig {
        scenario,
        id,
        transport: runtime::transport::TransportConfig::InProcess {
            hub: runtime::transport::InProcessHub::default(),
            me: id,
            role: proto::Role::Server,
            queue_len: 16,
        },
        record: path.clone(),
        tick: std::time::Duration::from_millis(10),
        sync_every: std::time::Duration::from_millis(50),
        origin: None,
    };
    let (_, rec, stats) = crate::process::start(&cfg, ClusterTime(0)).unwrap();
    assert!(stats.is_none());
    let mut rec = rec;
    for s in sample(10) {
        rec.append(&s).unwrap();
    }
    drop(rec);
    let before = read_all(&path).unwrap();
    let mut bytes = std::fs::read(&path).unwrap();
    let last = bytes.len() - 3;
    bytes[last] ^= 0x20; // inside the last record
    std::fs::write(&path, &bytes).unwrap();
    let (_, rec, stats) = crate::process::start(&cfg, ClusterTime(20_000)).unwrap();
    assert!(stats.is_some());
    drop(rec);
    let after = read_all(&path).unwrap();
    let n = before.records.len() - 1;
    assert_eq!(after.records[..n], before.records[..n]);
    let lost = before.records.last().unwrap();
    let lost_bytes = 8 + lost.encode().unwrap().len() as u64;
    assert_eq!(after.skipped_bytes(), lost_bytes);
    assert!(after.records[n..].iter().any(|s| matches!(
        s.record,
        Record::Decision(Decision::Resumed { records, skipped_bytes })
            if records == n as u64 && skipped_bytes == lost_bytes
    )));
}
