//! What every implementation shares: the bounded-queue drop policy and the receive-side
//! check that turns a frame into a validated envelope or a counted, logged rejection.

use super::stats::{TransportStats, bump};
use super::{Delivery, Event, SendError};
use proto::ids::NodeId;
use proto::msg::Envelope;
use proto::wire::{WireError, decode};
use tokio::sync::mpsc::{self, error::TrySendError};

/// Queue `item`: a droppable item meeting a full queue is dropped and counted in `dropped`;
/// any other item waits for room.
///
/// # Errors
/// [`SendError::Closed`] if the queue's receiver is gone.
pub(crate) async fn push<T>(
    tx: &mpsc::Sender<T>,
    item: T,
    droppable: bool,
    dropped: &std::sync::atomic::AtomicU64,
) -> Result<Delivery, SendError> {
    if droppable {
        match tx.try_send(item) {
            Ok(()) => Ok(Delivery::Queued),
            Err(TrySendError::Full(_)) => {
                bump(dropped);
                Ok(Delivery::Dropped)
            }
            Err(TrySendError::Closed(_)) => Err(SendError::Closed),
        }
    } else {
        tx.send(item)
            .await
            .map(|()| Delivery::Queued)
            .map_err(|_| SendError::Closed)
    }
}

/// Decode one received frame. A rejection is counted by kind, logged (rate-limited) with what
/// was wrong, and yields `None`; the caller goes on with the next frame. When the link is bound to a
/// node (`expected`), a frame claiming another source is rejected as invalid.
pub(crate) fn accept(
    frame: &[u8],
    stats: &TransportStats,
    expected: Option<NodeId>,
    transport: &'static str,
) -> Option<Envelope> {
    match decode(frame) {
        Ok(env) => match expected {
            Some(peer) if env.source != peer => {
                bump(&stats.rejected_invalid);
                if let Some(more) = stats.log_admits("frame from another source") {
                    tracing::warn!(transport, %peer, claimed = %env.source, more, "frame rejected: source does not match the link's peer");
                }
                None
            }
            _ => Some(env),
        },
        Err(e) => {
            reject(&e, frame.len(), stats, transport);
            None
        }
    }
}

/// Count and log a frame that failed to decode.
pub(crate) fn reject(e: &WireError, len: usize, stats: &TransportStats, transport: &'static str) {
    let (counter, kind) = match e {
        WireError::Oversized { .. } => (&stats.rejected_oversized, "oversized frame"),
        WireError::Version { .. } => (&stats.rejected_version, "wrong-version frame"),
        WireError::Invalid(_) => (&stats.rejected_invalid, "invalid frame"),
        WireError::Empty | WireError::Malformed(_) | WireError::TrailingBytes(_) => {
            (&stats.rejected_malformed, "malformed frame")
        }
    };
    bump(counter);
    if let Some(more) = stats.log_admits(kind) {
        tracing::warn!(transport, len, error = %e, more, "frame rejected ({more} more since the last line)");
    }
}

/// Hand a received envelope to the runtime under the drop policy, counting it as received.
///
/// # Errors
/// [`SendError::Closed`] if the inbox is gone.
pub(crate) async fn deliver(
    tx: &mpsc::Sender<Event>,
    from: NodeId,
    env: Envelope,
    stats: &TransportStats,
) -> Result<Delivery, SendError> {
    bump(&stats.received);
    let droppable = env.body.droppable();
    push(
        tx,
        Event::Message(super::Incoming { from, env }),
        droppable,
        &stats.dropped_inbox_full,
    )
    .await
}
