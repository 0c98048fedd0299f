//! What every real radio source shares: turning a received advertisement into a
//! [`TagReading`] (refusing RSSI no controller can report), and the bounded buffer a receiving
//! thread fills and [`proto::sensor::RadioSource::read`] drains, with the counts of what was
//! heard, refused and lost; and the frame source of a node without a camera. No IO here: the BLE
//! source (feature `ble`) and its tests use it.

use proto::sensor::TagReading;
use proto::sensor::mbd::BLE_RSSI_DBM;
use proto::{ClusterTime, TagId};
use std::collections::VecDeque;
use thiserror::Error;

/// Readings a radio source buffers between two reads by default (a node reads at its frame
/// rate; a few hundred tags advertising at 10 Hz fill a fifth of a second of it).
pub const DEFAULT_CAPACITY: usize = 1024;

/// A received advertisement that is not a reading.
#[derive(Clone, Debug, Error, PartialEq)]
pub enum Refused {
    #[error("tag {tag}: RSSI {dbm} dBm is not one a BLE controller reports (-127..=20)")]
    Rssi { tag: TagId, dbm: i32 },
}

/// What a radio source did since it opened.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct RadioCounters {
    /// Readings buffered.
    pub heard: u64,
    /// Advertisements refused (impossible RSSI).
    pub refused: u64,
    /// Readings lost because the buffer was full (the oldest go first).
    pub overflowed: u64,
    /// Adapter or bus errors (each followed by a retry).
    pub adapter_errors: u64,
}

/// The reading of an advertisement from Bluetooth address `address` (most significant byte
/// first, as printed) received at `time` with `rssi_dbm`.
///
/// # Errors
/// [`Refused::Rssi`] for an RSSI outside −127..=20 dBm (127 is the controller's "not
/// available").
pub fn reading(address: [u8; 6], rssi_dbm: i32, time: ClusterTime) -> Result<TagReading, Refused> {
    let tag = TagId(address.iter().fold(0u64, |v, b| (v << 8) | u64::from(*b)));
    let dbm = f64::from(rssi_dbm);
    if !BLE_RSSI_DBM.contains(&dbm) {
        return Err(Refused::Rssi { tag, dbm: rssi_dbm });
    }
    Ok(TagReading { tag, dbm, time })
}

/// A bounded first-in first-out buffer of readings; when full the oldest is dropped and
/// counted (the newest reading of a tag is the one a node's answers carry).
#[derive(Debug)]
pub struct ReadingBuffer {
    queue: VecDeque<TagReading>,
    capacity: usize,
    counters: RadioCounters,
}

impl ReadingBuffer {
    /// A buffer of at most `capacity` readings (at least one).
    pub fn new(capacity: usize) -> ReadingBuffer {
        let capacity = capacity.max(1);
        ReadingBuffer {
            queue: VecDeque::with_capacity(capacity),
            capacity,
            counters: RadioCounters::default(),
        }
    }

    /// Buffer an advertisement's reading, or count why not.
    pub fn offer(&mut self, advertisement: Result<TagReading, Refused>) {
        match advertisement {
            Ok(r) => self.push(r),
            Err(e) => {
                self.counters.refused += 1;
                tracing::debug!(error = %e, "advertisement refused");
            }
        }
    }

    /// Buffer a reading, dropping the oldest when full.
    pub fn push(&mut self, r: TagReading) {
        if self.queue.len() == self.capacity {
            self.queue.pop_front();
            self.counters.overflowed += 1;
        }
        self.queue.push_back(r);
        self.counters.heard += 1;
    }

    /// Count an adapter error.
    pub fn adapter_error(&mut self) {
        self.counters.adapter_errors += 1;
    }

    /// Move every buffered reading to `out`, oldest first.
    pub fn drain_into(&mut self, out: &mut Vec<TagReading>) {
        out.extend(self.queue.drain(..));
    }

    pub fn len(&self) -> usize {
        self.queue.len()
    }

    pub fn is_empty(&self) -> bool {
        self.queue.is_empty()
    }

    pub fn counters(&self) -> RadioCounters {
        self.counters
    }
}

/// The frame source of a radio-only node: it has no camera (its core never captures, so this
/// is never asked for a frame; asked, it says it has none).
#[derive(Clone, Copy, Debug, Default)]
pub struct NoCamera;

impl proto::sensor::FrameSource for NoCamera {
    fn size(&self) -> (u32, u32) {
        (1, 1)
    }

    fn capture(
        &mut self,
        _now: ClusterTime,
        _frame: &mut proto::sensor::Frame,
    ) -> Result<bool, proto::sensor::SourceError> {
        Ok(false)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const ADDR: [u8; 6] = [0xe7, 0x8f, 0x13, 0x56, 0x24, 0xce];

    #[test]
    fn an_advertisement_becomes_a_reading_of_its_mac() {
        let r = reading(ADDR, -71, ClusterTime(5)).unwrap();
        assert_eq!(r.tag.to_string(), "e7:8f:13:56:24:ce");
        assert_eq!(r.tag, TagId::parse_mac("e78f135624ce").unwrap());
        assert_eq!((r.dbm, r.time), (-71.0, ClusterTime(5)));
        assert!(reading(ADDR, -127, ClusterTime(0)).is_ok());
        assert!(reading(ADDR, 20, ClusterTime(0)).is_ok());
    }

    #[test]
    fn impossible_rssi_is_refused_and_counted() {
        let mut b = ReadingBuffer::new(4);
        for dbm in [127, 21, -128, -1000] {
            let e = reading(ADDR, dbm, ClusterTime(0)).unwrap_err();
            assert!(e.to_string().contains(&dbm.to_string()), "{e}");
            b.offer(Err(e));
        }
        assert!(b.is_empty());
        assert_eq!(b.counters().refused, 4);
        assert_eq!(b.counters().heard, 0);
    }

    #[test]
    fn a_full_buffer_drops_the_oldest_and_counts_it() {
        let mut b = ReadingBuffer::new(3);
        for k in 0..5 {
            b.offer(reading(ADDR, -60 - k, ClusterTime(i64::from(k))));
        }
        assert_eq!(b.len(), 3);
        let mut out = Vec::new();
        b.drain_into(&mut out);
        let times: Vec<i64> = out.iter().map(|r| r.time.0).collect();
        assert_eq!(times, vec![2, 3, 4], "oldest dropped, order kept");
        assert!(b.is_empty());
        let c = b.counters();
        assert_eq!((c.heard, c.overflowed, c.refused), (5, 2, 0));
        b.adapter_error();
        assert_eq!(b.counters().adapter_errors, 1);
    }
}
