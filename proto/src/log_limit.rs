//! Rate-limited logging of repeated events: one line per kind of event and interval, carrying
//! how many of that kind were not logged since the last line.
//!
//! A log line per rejected input lets one peer fill a disk (a 10 s flood of malformed frames
//! once grew two nodes' logs to 1.1 GB each). Every node — transports and node cores alike —
//! asks a [`LogLimiter`] before logging something a peer can make happen at will; the
//! counters say how many there were, the log says that they happen. Sans-IO: the caller passes
//! the time (nanoseconds on any monotonic or cluster clock), so cores stay clock-free.

use std::collections::BTreeMap;

/// How often one kind of event is logged by default: at most once per five seconds.
pub const DEFAULT_INTERVAL_NS: i64 = 5_000_000_000;

/// Per kind of event: when it was last logged and how many were suppressed since.
#[derive(Clone, Debug, PartialEq, Eq)]
struct Slot {
    last_logged_ns: i64,
    suppressed: u64,
}

/// Decides which occurrences of repeated events are logged. The first occurrence of a kind is
/// logged at once; later ones only when `interval` has passed since that kind's last line,
/// and that line carries the count of those suppressed in between.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct LogLimiter {
    interval_ns: i64,
    slots: BTreeMap<&'static str, Slot>,
}

impl Default for LogLimiter {
    fn default() -> Self {
        LogLimiter::new(DEFAULT_INTERVAL_NS)
    }
}

impl LogLimiter {
    /// A limiter logging each kind at most once per `interval_ns` (at least 1 ns).
    pub fn new(interval_ns: i64) -> Self {
        LogLimiter {
            interval_ns: interval_ns.max(1),
            slots: BTreeMap::new(),
        }
    }

    /// One occurrence of `kind` at `now_ns`. `Some(suppressed)` means: log this one now, and
    /// say that `suppressed` more of its kind happened since the last line. `None`: counted,
    /// stay quiet.
    pub fn admit(&mut self, now_ns: i64, kind: &'static str) -> Option<u64> {
        match self.slots.get_mut(kind) {
            None => {
                self.slots.insert(
                    kind,
                    Slot {
                        last_logged_ns: now_ns,
                        suppressed: 0,
                    },
                );
                Some(0)
            }
            Some(slot) if now_ns.saturating_sub(slot.last_logged_ns) >= self.interval_ns => {
                slot.last_logged_ns = now_ns;
                Some(std::mem::take(&mut slot.suppressed))
            }
            Some(slot) => {
                slot.suppressed += 1;
                None
            }
        }
    }

    /// Kinds with occurrences not logged yet whose interval has passed at `now_ns`, with their
    /// counts; they are reset as if logged now. For a periodic summary when a flood stops.
    pub fn overdue(&mut self, now_ns: i64) -> Vec<(&'static str, u64)> {
        let mut out = Vec::new();
        for (kind, slot) in &mut self.slots {
            if slot.suppressed > 0 && now_ns.saturating_sub(slot.last_logged_ns) >= self.interval_ns {
                out.push((*kind, std::mem::take(&mut slot.suppressed)));
                slot.last_logged_ns = now_ns;
            }
        }
        out
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_flood_logs_one_line_per_interval_with_the_count_of_the_rest() {
        let mut l = LogLimiter::new(1_000);
        let mut lines = Vec::new();
        // 10 000 events, one per nanosecond-tick of 1, over 10 intervals.
        for t in 0..10_000 {
            if let Some(more) = l.admit(t, "frame rejected") {
                lines.push((t, more));
            }
        }
        assert_eq!(lines.len(), 10, "{lines:?}");
        assert_eq!(lines[0], (0, 0));
        assert_eq!(lines[1], (1_000, 999));
        let logged: u64 = lines.iter().map(|(_, n)| n + 1).sum();
        assert_eq!(logged + 999, 10_000, "every event is logged or counted");
    }

    #[test]
    fn kinds_are_limited_apart_and_overdue_counts_are_flushed_once() {
        let mut l = LogLimiter::new(100);
        assert_eq!(l.admit(0, "a"), Some(0));
        assert_eq!(l.admit(1, "b"), Some(0));
        assert_eq!(l.admit(2, "a"), None);
        assert_eq!(l.admit(3, "a"), None);
        assert!(l.overdue(50).is_empty());
        assert_eq!(l.overdue(150), vec![("a", 2)]);
        assert!(l.overdue(400).is_empty());
        assert_eq!(l.admit(400, "a"), Some(0));
    }
}
