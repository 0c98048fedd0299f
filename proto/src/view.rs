//! The visualization node's feed (paper 004 §3.1): what a viewer asks the server for, and what
//! the server sends it at the filter's step rate — every global track with its owner and
//! posterior, every node's liveness, mode and health, and the latest handovers.
//!
//! A viewer has no say: the server admits it on its first [`ViewSubscribe`] (with an id the
//! scenario does not declare) and only ever sends it [`ViewUpdate`]s. Both messages are
//! droppable: a subscription is renewed every second, and an update is superseded by the next,
//! so a slow viewer never slows the server. An update is bounded to fit one frame; a cluster
//! too large for one is sent as several *parts* of the same round, each complete in itself
//! (every part repeats the handovers and counters), so losing one loses only its slice.

use crate::ids::{NodeId, Role, TargetId};
use crate::msg::{Contributor, NodeStatus, Vec6};
use crate::time::ClusterTime;
use serde::{Deserialize, Serialize};

/// Tracks one update carries at most.
pub const MAX_VIEW_TRACKS: usize = 24;
/// Nodes one update carries at most.
pub const MAX_VIEW_NODES: usize = 32;
/// Recent handovers one update repeats at most.
pub const MAX_VIEW_HANDOVERS: usize = 8;
/// Contributors of one track an update names at most.
pub const MAX_VIEW_CONTRIBUTORS: usize = 16;
/// Parts of one round at most (so at most this many times the per-update limits are shown).
pub const MAX_VIEW_PARTS: u16 = 32;
/// The shortest update period a viewer may ask for, ms.
pub const MIN_VIEW_PERIOD_MS: u32 = 50;

/// A viewer asks for the feed (and renews the request; the server forgets a viewer that went
/// silent).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct ViewSubscribe {
    /// How often it wants an update, ms; 0 for the filter's step period. The server sends no
    /// faster than [`MIN_VIEW_PERIOD_MS`].
    pub period_ms: u32,
}

/// One global track as the server holds it.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct ViewTrack {
    pub global: TargetId,
    /// The head that owns it, and that head's local id for it (once the server has seen it).
    pub owner: NodeId,
    pub local: Option<TargetId>,
    /// Time of the posterior (the owner's cluster time).
    pub time: ClusterTime,
    /// `[X Y Z Vx Vy Vz]`, m and m/s.
    pub mean: Vec6,
    /// Position covariance, upper triangle `[xx, xy, xz, yy, yz, zz]`, m².
    pub cov_pos: [f64; 6],
    /// Who contributed to the owner's latest step, at most [`MAX_VIEW_CONTRIBUTORS`].
    pub contributors: Vec<Contributor>,
}

/// One node as the server sees it.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct ViewNode {
    pub node: NodeId,
    pub role: Role,
    /// The server counts it as up.
    pub up: bool,
    /// Since the server last heard from it, ms.
    pub silent_ms: u64,
    /// A camera's current head.
    pub head: Option<NodeId>,
    /// Its latest status (mode, frames, drops, rejected frames, sync).
    pub status: Option<NodeStatus>,
    /// A head's latest filter step and its late contributions (cumulative).
    pub steps: u64,
    pub late: u64,
    /// Its messages the server rejected.
    pub rejected: u64,
    /// Its frames that never reached the server (gaps in its sequence numbers).
    pub lost: u64,
}

/// Why a track changed hands.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub enum HandoverCause {
    /// It left its owner's region.
    Region,
    /// Its owner went down.
    Failover,
    /// Another head that tracks it took it over without a handover.
    OwnerChanged,
}

/// A track moving from one head to another.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct ViewHandover {
    /// Increases by one per handover the server made: a viewer shows each once.
    pub seq: u64,
    pub time: ClusterTime,
    pub global: TargetId,
    pub from: Option<NodeId>,
    pub to: NodeId,
    pub cause: HandoverCause,
}

/// The server's own counts.
#[derive(Clone, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
pub struct ViewCounters {
    /// Messages it received, and rejected.
    pub received: u64,
    pub rejected: u64,
    pub handovers: u64,
    /// Messages it could not deliver (view updates to slow viewers among them).
    pub undelivered: u64,
}

/// What the server sends a viewer every period: one part of a round.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct ViewUpdate {
    /// Increases by one per round sent to this viewer.
    pub round: u64,
    /// This part's index and the round's number of parts (≤ [`MAX_VIEW_PARTS`]).
    pub part: u16,
    pub parts: u16,
    /// The server's cluster time of the round.
    pub time: ClusterTime,
    /// The global tracks of this part, in id order, at most [`MAX_VIEW_TRACKS`], and how many
    /// the server holds.
    pub tracks: Vec<ViewTrack>,
    pub tracks_total: u32,
    /// The nodes of this part, in id order, at most [`MAX_VIEW_NODES`], and how many the
    /// server knows.
    pub nodes: Vec<ViewNode>,
    pub nodes_total: u32,
    /// The latest handovers, oldest first, at most [`MAX_VIEW_HANDOVERS`].
    pub handovers: Vec<ViewHandover>,
    pub counters: ViewCounters,
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::msg::{Envelope, Message, Mode};
    use crate::observation::Kinds;

    /// An update with every list at its maximum and every number at its widest encoding fits
    /// one frame, so the server never makes one a transport must refuse.
    #[test]
    fn the_largest_update_fits_one_frame() {
        let wide = u64::MAX;
        let track = ViewTrack {
            global: TargetId(u32::MAX),
            owner: NodeId(u32::MAX),
            local: Some(TargetId(u32::MAX)),
            time: ClusterTime(i64::MIN),
            mean: [f64::MAX; 6],
            cov_pos: [f64::MAX; 6],
            contributors: vec![
                Contributor {
                    node: NodeId(u32::MAX),
                    kinds: Kinds(u8::MAX),
                };
                MAX_VIEW_CONTRIBUTORS
            ],
        };
        let node = ViewNode {
            node: NodeId(u32::MAX),
            role: Role::Viewer,
            up: true,
            silent_ms: wide,
            head: Some(NodeId(u32::MAX)),
            status: Some(NodeStatus {
                mode: Mode::Inactive,
                time_in_mode_ns: [wide; 3],
                frames: wide,
                detections: wide,
                dropped: wide,
                rejected: wide,
                sync_offset_ns: i64::MIN,
                sync_error_ns: i64::MIN,
                bytes_sent: wide,
            }),
            steps: wide,
            late: wide,
            rejected: wide,
            lost: wide,
        };
        let handover = ViewHandover {
            seq: wide,
            time: ClusterTime(i64::MIN),
            global: TargetId(u32::MAX),
            from: Some(NodeId(u32::MAX)),
            to: NodeId(u32::MAX),
            cause: HandoverCause::OwnerChanged,
        };
        let env = Envelope {
            source: NodeId(u32::MAX),
            seq: wide,
            time: ClusterTime(i64::MIN),
            body: Message::ViewUpdate(ViewUpdate {
                round: wide,
                part: MAX_VIEW_PARTS - 1,
                parts: MAX_VIEW_PARTS,
                time: ClusterTime(i64::MIN),
                tracks: vec![track; MAX_VIEW_TRACKS],
                tracks_total: u32::MAX,
                nodes: vec![node; MAX_VIEW_NODES],
                nodes_total: u32::MAX,
                handovers: vec![handover; MAX_VIEW_HANDOVERS],
                counters: ViewCounters {
                    received: wide,
                    rejected: wide,
                    handovers: wide,
                    undelivered: wide,
                },
            }),
        };
        let frame = crate::wire::encode(&env).expect("the largest update encodes");
        assert!(frame.len() <= crate::MAX_FRAME_BYTES, "{} bytes", frame.len());
        assert_eq!(crate::wire::decode(&frame).unwrap(), env);
    }
}
