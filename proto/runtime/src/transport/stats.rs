//! Counters every transport keeps: what was sent, received, dropped, rejected and how links
//! came and went. Atomics, so the hot path never locks; [`TransportStats::snapshot`] gives a
//! serializable copy for logs, status messages and the `ocelli peer` JSON lines. Rejections
//! are logged through the stats' [`LogLimiter`]: one line per kind and interval, with a count.

use proto::log_limit::LogLimiter;
use serde::{Deserialize, Serialize};
use std::sync::Mutex;
use std::sync::atomic::{AtomicU64, Ordering};

/// Live counters of one endpoint. Shared (`Arc`) between the endpoint, its tasks and threads.
#[derive(Debug, Default)]
pub struct TransportStats {
    pub sent: AtomicU64,
    pub received: AtomicU64,
    /// Droppable messages not queued because the outgoing queue was full.
    pub dropped_queue_full: AtomicU64,
    /// Droppable messages not handed to the runtime because the inbox was full.
    pub dropped_inbox_full: AtomicU64,
    /// Frames iceoryx2 delivered to no receiver: none was alive, or its buffer was full.
    pub dropped_undelivered: AtomicU64,
    pub rejected_malformed: AtomicU64,
    pub rejected_oversized: AtomicU64,
    pub rejected_version: AtomicU64,
    /// Frames that decoded but failed validation, or came from the wrong node on a link.
    pub rejected_invalid: AtomicU64,
    /// Handshakes refused (by us or by the peer).
    pub rejected_handshake: AtomicU64,
    /// Sends to a node this endpoint has no link to.
    pub unroutable: AtomicU64,
    /// Envelopes the local node tried to send that failed to encode.
    pub encode_errors: AtomicU64,
    /// Connection attempts after the first one on a dialed link.
    pub reconnects: AtomicU64,
    pub peers_up: AtomicU64,
    pub peers_lost: AtomicU64,
    pub heartbeats_sent: AtomicU64,
    pub heartbeats_received: AtomicU64,
    /// Handshakes refused because the peer's certificate or claim does not prove who it says
    /// it is (a certificate of another node or CA, an id or role the scenario does not give).
    pub rejected_identity: AtomicU64,
    /// Connections refused because the node already has a live link to that id.
    pub rejected_duplicate: AtomicU64,
    /// Connections closed by a listener's limits: too many handshakes at once, or one that did
    /// not finish in time.
    pub rejected_connections: AtomicU64,
    /// Times a link was read more slowly because its peer sent faster than the per-link limit.
    pub throttled: AtomicU64,
    /// Decides which rejections are logged (the counters above count them all).
    pub(crate) log: Mutex<LogLimiter>,
    /// Bytes of the encoded frames this endpoint put on its links: every message it queued
    /// and the transport's own heartbeats (framing and TCP/IP headers not counted).
    pub bytes_sent: AtomicU64,
}

/// A point-in-time copy of [`TransportStats`].
#[derive(Clone, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
pub struct StatsSnapshot {
    pub sent: u64,
    pub received: u64,
    pub dropped_queue_full: u64,
    pub dropped_inbox_full: u64,
    pub dropped_undelivered: u64,
    pub rejected_malformed: u64,
    pub rejected_oversized: u64,
    pub rejected_version: u64,
    pub rejected_invalid: u64,
    pub rejected_handshake: u64,
    pub unroutable: u64,
    pub encode_errors: u64,
    pub reconnects: u64,
    pub peers_up: u64,
    pub peers_lost: u64,
    pub heartbeats_sent: u64,
    pub heartbeats_received: u64,
    #[serde(default)]
    pub rejected_identity: u64,
    #[serde(default)]
    pub rejected_duplicate: u64,
    #[serde(default)]
    pub rejected_connections: u64,
    #[serde(default)]
    pub throttled: u64,
    #[serde(default)]
    pub bytes_sent: u64,
}

/// Add one to a counter.
pub(crate) fn bump(c: &AtomicU64) {
    c.fetch_add(1, Ordering::Relaxed);
}

/// Add `n` to a counter.
pub(crate) fn add(c: &AtomicU64, n: usize) {
    c.fetch_add(n as u64, Ordering::Relaxed);
}

impl TransportStats {
    pub fn snapshot(&self) -> StatsSnapshot {
        let g = |c: &AtomicU64| c.load(Ordering::Relaxed);
        StatsSnapshot {
            sent: g(&self.sent),
            received: g(&self.received),
            dropped_queue_full: g(&self.dropped_queue_full),
            dropped_inbox_full: g(&self.dropped_inbox_full),
            dropped_undelivered: g(&self.dropped_undelivered),
            rejected_malformed: g(&self.rejected_malformed),
            rejected_oversized: g(&self.rejected_oversized),
            rejected_version: g(&self.rejected_version),
            rejected_invalid: g(&self.rejected_invalid),
            rejected_handshake: g(&self.rejected_handshake),
            unroutable: g(&self.unroutable),
            encode_errors: g(&self.encode_errors),
            reconnects: g(&self.reconnects),
            peers_up: g(&self.peers_up),
            peers_lost: g(&self.peers_lost),
            heartbeats_sent: g(&self.heartbeats_sent),
            heartbeats_received: g(&self.heartbeats_received),
            rejected_identity: g(&self.rejected_identity),
            rejected_duplicate: g(&self.rejected_duplicate),
            rejected_connections: g(&self.rejected_connections),
            throttled: g(&self.throttled),
            bytes_sent: g(&self.bytes_sent),
        }
    }

    /// Whether to log this occurrence of `kind` (see [`LogLimiter`]): `Some(n)` — log it, and
    /// say `n` more happened since the last line of its kind.
    pub(crate) fn log_admits(&self, kind: &'static str) -> Option<u64> {
        let mut l = self.log.lock().unwrap_or_else(|p| p.into_inner());
        l.admit(monotonic_ns(), kind)
    }
}

/// Nanoseconds since this process first asked: the transports' clock for log limits.
fn monotonic_ns() -> i64 {
    use std::sync::OnceLock;
    use std::time::Instant;
    static START: OnceLock<Instant> = OnceLock::new();
    // The transport is a runtime: it owns a clock (node cores are given theirs).
    #[allow(clippy::disallowed_methods)]
    let start = *START.get_or_init(Instant::now);
    i64::try_from(start.elapsed().as_nanos()).unwrap_or(i64::MAX)
}
