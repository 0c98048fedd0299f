//! What the server decided, as recorded next to the messages it saw.
//!
//! Decisions are not protocol: they never cross a process boundary, so they are serialized with
//! `serde_json` inside the recording (not with the wire encoding, which is reserved for
//! `proto` messages). Every state change of the server that is not a direct consequence of a
//! received message is a decision, which is what makes a recording replayable.

use proto::{NodeId, Role, TargetId};
use serde::{Deserialize, Serialize};

/// Why a track moved to another head.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum HandoverReason {
    /// The target left the owning head's region and entered the new head's.
    Region,
    /// The owning head was marked down.
    Failover,
}

/// One decision of the server.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(tag = "kind", rename_all = "snake_case")]
pub enum Decision {
    /// A node completed the handshake (or, after a server restart, simply spoke first).
    Admitted { node: NodeId, role: Role },
    /// A handshake was refused.
    Refused { node: NodeId, reason: String },
    /// A message was refused (unexpected kind, unknown sender, undecodable frame).
    Rejected {
        source: Option<NodeId>,
        what: String,
        reason: String,
    },
    /// A node stopped answering.
    Down { node: NodeId, silent_ms: u64 },
    /// A node that was down spoke again and is re-admitted.
    Up { node: NodeId },
    /// A camera now reports to `head` (instead of `from`).
    Assigned {
        camera: NodeId,
        head: NodeId,
        from: Option<NodeId>,
    },
    /// A head's local track got a new global id.
    NewGlobal {
        head: NodeId,
        local: TargetId,
        global: TargetId,
    },
    /// A head's local track carried a known global id (it continues a handed-over track).
    Claimed {
        head: NodeId,
        local: TargetId,
        global: TargetId,
    },
    /// A head's local track was merged into an existing global track after agreeing with it
    /// for the hysteresis count.
    Merged {
        head: NodeId,
        local: TargetId,
        global: TargetId,
    },
    /// A merged local track disagreed for the hysteresis count and got its own global id.
    Split {
        head: NodeId,
        local: TargetId,
        from: TargetId,
        global: TargetId,
    },
    /// A global track moved to another head, which starts from the last posterior.
    Handover {
        global: TargetId,
        from: Option<NodeId>,
        to: NodeId,
        reason: HandoverReason,
    },
    /// The owner stopped reporting a global track that another head still reports, or that head
    /// reports it inside its own region while it is outside the owner's; that head owns it now
    /// (it already tracks it, so no handover message is sent).
    OwnerChanged {
        global: TargetId,
        from: NodeId,
        to: NodeId,
    },
    /// Two global tracks stayed together: `global` is absorbed into the older `into`.
    Absorbed { global: TargetId, into: TargetId },
    /// No head reported a global track for the track timeout; it is dropped.
    Lost { global: TargetId },
    /// A head's local track fell silent and its mapping was forgotten.
    Forgotten { head: NodeId, local: TargetId },
    /// The server restarted from its recording; every known node gets a fresh liveness grace.
    Resumed { records: u64, skipped_bytes: u64 },
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn decisions_round_trip_through_json() {
        let all = vec![
            Decision::Admitted {
                node: NodeId(3),
                role: Role::Head,
            },
            Decision::Handover {
                global: TargetId(7),
                from: None,
                to: NodeId(2),
                reason: HandoverReason::Failover,
            },
            Decision::Resumed {
                records: 10,
                skipped_bytes: 3,
            },
        ];
        for d in all {
            let s = serde_json::to_string(&d).unwrap();
            assert_eq!(serde_json::from_str::<Decision>(&s).unwrap(), d);
        }
        let s = serde_json::to_string(&Decision::Lost { global: TargetId(4) }).unwrap();
        assert_eq!(s, r#"{"kind":"lost","global":4}"#);
    }
}
