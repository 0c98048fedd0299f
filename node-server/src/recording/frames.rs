//! Finding records in a recording's bytes: what the bytes at a position hold, and how far to
//! skip past damage to the next valid record. Pure functions over byte slices, shared by
//! [`super::Reader`] (a whole file) and [`crate::tail::Tailer`] (a file that is still growing).
//!
//! A *valid* record is a frame `u32 LE len | u32 LE crc32(payload) | payload` with
//! `1 ≤ len ≤` [`MAX_RECORD_BYTES`], a matching CRC, and a payload that decodes as a
//! [`Stamped`]. Past damage the scanner tries every byte offset in turn and stops at the first
//! valid record. While scanning it decodes a candidate before checksumming it: garbage almost
//! never decodes, so a plausible-looking length costs a failed decode (usually at its first
//! byte) rather than a CRC over up to [`MAX_RECORD_BYTES`].
//!
//! A false resynchronisation needs a 32-bit CRC to match by chance *and* the bytes to decode,
//! so it does not happen by accident. It can be made on purpose: the payload of a damaged
//! record may carry bytes a peer sent, and those could hold a forged frame that the scan finds.
//! Only damage exposes it, and the forged record is reported like any other, so it is noted
//! here rather than defended against.

use super::{Damage, MAX_RECORD_BYTES};
use crate::record::Stamped;

/// Bytes of a record's frame header (length and CRC).
pub(crate) const FRAME_HEADER: usize = 8;

/// What the bytes at one position hold.
// Short-lived: the record moves on to the caller at once, so boxing it would only add an
// allocation per record.
#[allow(clippy::large_enum_variant)]
enum Candidate {
    /// A valid record and the bytes of its frame.
    Valid { record: Stamped, frame_len: usize },
    /// A whole frame whose CRC holds but whose payload this build cannot decode.
    Undecodable { frame_len: usize },
    /// A frame that runs past the bytes available (`ShortHeader` or `ShortPayload`).
    Incomplete(Damage),
    /// Not a record.
    Invalid(Damage),
}

/// Classify the frame at the start of `bytes`. `scanning` decodes before checksumming (cheap
/// rejection of garbage) and reports an undecodable frame as invalid.
fn candidate(bytes: &[u8], scanning: bool) -> Candidate {
    let Some(head) = bytes.first_chunk::<FRAME_HEADER>() else {
        return Candidate::Incomplete(Damage::ShortHeader);
    };
    let len = u32::from_le_bytes([head[0], head[1], head[2], head[3]]);
    let crc = u32::from_le_bytes([head[4], head[5], head[6], head[7]]);
    if len == 0 || len > MAX_RECORD_BYTES {
        return Candidate::Invalid(Damage::BadLength { len });
    }
    let frame_len = FRAME_HEADER + len as usize;
    let Some(payload) = bytes.get(FRAME_HEADER..frame_len) else {
        return Candidate::Incomplete(Damage::ShortPayload { len });
    };
    if scanning {
        let Ok(record) = Stamped::decode(payload) else {
            return Candidate::Invalid(Damage::Undecodable);
        };
        if crc32fast::hash(payload) != crc {
            return Candidate::Invalid(Damage::Checksum);
        }
        return Candidate::Valid { record, frame_len };
    }
    if crc32fast::hash(payload) != crc {
        return Candidate::Invalid(Damage::Checksum);
    }
    match Stamped::decode(payload) {
        Ok(record) => Candidate::Valid { record, frame_len },
        Err(_) => Candidate::Undecodable { frame_len },
    }
}

/// What to do at a position where a record is expected.
#[derive(Debug)]
#[allow(clippy::large_enum_variant)] // as `Candidate`
pub(crate) enum Step {
    /// Nothing is left.
    End,
    /// A valid record; consume `frame_len` bytes.
    Record { record: Stamped, frame_len: usize },
    /// Damage: skip `bytes` (to the next valid record, to a frame that needs more bytes to
    /// judge, or to the end), because of what was found at the start.
    Skip { bytes: usize, damage: Damage },
    /// The frame at the start runs past the bytes given: `need` bytes from the start would
    /// settle it (more may exist), and `damage` says what is missing.
    NeedMore { need: usize, damage: Damage },
}

/// Judge the bytes at the start of `window`, where a record is expected. `at_end` says that
/// nothing follows `window` (a whole file); otherwise more bytes may still arrive.
pub(crate) fn step(window: &[u8], at_end: bool) -> Step {
    if window.is_empty() && at_end {
        return Step::End;
    }
    let damage = match candidate(window, false) {
        Candidate::Valid { record, frame_len } => return Step::Record { record, frame_len },
        Candidate::Undecodable { frame_len } => {
            return Step::Skip {
                bytes: frame_len,
                damage: Damage::Undecodable,
            };
        }
        Candidate::Incomplete(damage) if !at_end => {
            return Step::NeedMore {
                need: needed(window),
                damage,
            };
        }
        Candidate::Incomplete(damage) | Candidate::Invalid(damage) => damage,
    };
    Step::Skip {
        bytes: resync(window, at_end),
        damage,
    }
}

/// Bytes from the start of `window` that settle the frame there.
fn needed(window: &[u8]) -> usize {
    match window.first_chunk::<4>() {
        Some(len) => FRAME_HEADER + u32::from_le_bytes(*len) as usize,
        None => FRAME_HEADER,
    }
}

/// Where to resume after damage at the start of `window`: the first later offset holding a
/// valid record or, when more bytes may come, a frame that cannot be judged yet; else the end.
fn resync(window: &[u8], at_end: bool) -> usize {
    for at in 1..window.len() {
        match candidate(&window[at..], true) {
            Candidate::Valid { .. } => return at,
            Candidate::Incomplete(_) if !at_end => return at,
            _ => {}
        }
    }
    window.len()
}

/// The first offset at or after `from` in `window` that holds a whole valid record. A reader
/// of a growing file uses it to tell a record still being written (nothing valid follows it)
/// from damage that only looks like one.
pub(crate) fn next_valid(window: &[u8], from: usize) -> Option<usize> {
    (from..window.len()).find(|&at| matches!(candidate(&window[at..], true), Candidate::Valid { .. }))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::record::Record;
    use proto::ClusterTime;

    fn framed(k: i64) -> Vec<u8> {
        let payload = Stamped::new(ClusterTime(k), Record::Tick).encode().unwrap();
        let mut out = (payload.len() as u32).to_le_bytes().to_vec();
        out.extend_from_slice(&crc32fast::hash(&payload).to_le_bytes());
        out.extend_from_slice(&payload);
        out
    }

    #[test]
    fn a_whole_record_is_read_and_an_empty_end_ends() {
        let one = framed(7);
        match step(&one, true) {
            Step::Record { record, frame_len } => {
                assert_eq!(record, Stamped::new(ClusterTime(7), Record::Tick));
                assert_eq!(frame_len, one.len());
            }
            other => panic!("expected a record, got {other:?}"),
        }
        assert!(matches!(step(&[], true), Step::End));
    }

    #[test]
    fn a_cut_record_waits_in_a_growing_file_and_is_a_torn_tail_at_the_end() {
        let one = framed(1);
        let cut = &one[..one.len() - 1];
        let len = one.len() as u32 - 8;
        match step(cut, false) {
            Step::NeedMore { need, damage } => {
                assert_eq!(need, one.len());
                assert_eq!(damage, Damage::ShortPayload { len });
            }
            other => panic!("expected to wait, got {other:?}"),
        }
        match step(cut, true) {
            Step::Skip { bytes, damage } => {
                assert_eq!(bytes, cut.len());
                assert_eq!(damage, Damage::ShortPayload { len });
            }
            other => panic!("expected a torn tail, got {other:?}"),
        }
        assert!(matches!(
            step(&one[..3], false),
            Step::NeedMore {
                need: 8,
                damage: Damage::ShortHeader
            }
        ));
    }

    /// Three garbage bytes, then a record: in a whole file the skip is exactly the garbage; in a
    /// growing one it stops early at a frame that cannot be judged yet (its length claims bytes
    /// that have not arrived), and `next_valid` finds the record behind it.
    #[test]
    fn damage_is_skipped_to_the_next_valid_record() {
        let mut bytes = vec![0xff, 0x00, 0x13];
        bytes.extend_from_slice(&framed(2));
        match step(&bytes, true) {
            Step::Skip { bytes, damage } => {
                assert_eq!(bytes, 3);
                // The length field is the garbage and the record's first length byte (9).
                assert_eq!(damage, Damage::BadLength { len: 0x0913_00ff });
            }
            other => panic!("expected a skip, got {other:?}"),
        }
        // At offset 1 the length reads 0x0009_1300: plausible, and longer than what is there.
        assert!(matches!(step(&bytes, false), Step::Skip { bytes: 1, .. }));
        assert!(matches!(
            step(&bytes[1..], false),
            Step::NeedMore {
                need: 0x0009_1308,
                ..
            }
        ));
        assert_eq!(next_valid(&bytes, 0), Some(3));
        assert_eq!(next_valid(&bytes, 4), None);
    }

    #[test]
    fn a_checksummed_frame_that_does_not_decode_is_skipped_whole() {
        let payload = [0xee; 12]; // kind 0xee is no record kind
        let mut bytes = (payload.len() as u32).to_le_bytes().to_vec();
        bytes.extend_from_slice(&crc32fast::hash(&payload).to_le_bytes());
        bytes.extend_from_slice(&payload);
        bytes.extend_from_slice(&framed(3));
        match step(&bytes, true) {
            Step::Skip { bytes, damage } => {
                assert_eq!(bytes, 8 + payload.len());
                assert_eq!(damage, Damage::Undecodable);
            }
            other => panic!("expected a skip, got {other:?}"),
        }
    }
}
