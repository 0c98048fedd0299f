//! The one contract every node core implements, and what it emits.
//!
//! A core is a sans-IO state machine: [`Node::handle`] is given the current cluster time and
//! one [`Input`] and returns the messages it wants sent. It opens no socket, reads no clock,
//! spawns no thread and draws no unseeded random number. Two runtimes drive the same cores:
//! the process runtime (one OS process per node, crate `runtime`) and the simulation (every
//! node in one process on a virtual clock, crate `sim`).

use crate::ids::NodeId;
use crate::msg::{Envelope, Message};
use crate::time::ClusterTime;

/// A message a core wants delivered to `to`. The runtime wraps it in an envelope (source,
/// sequence number, cluster time) and sends it on the link to that node.
#[derive(Clone, Debug, PartialEq)]
pub struct Outgoing {
    pub to: NodeId,
    pub body: Message,
}

impl Outgoing {
    pub fn new(to: NodeId, body: Message) -> Self {
        Outgoing { to, body }
    }
}

/// Everything a runtime gives a node core. Closed: a new kind of input is a new variant here,
/// and every runtime and core must say what it does with it.
// A message is moved once from the transport into the core; boxing it would cost an allocation
// per frame to save bytes on the rare other inputs.
#[allow(clippy::large_enum_variant)]
#[derive(Debug)]
pub enum Input<S> {
    /// A decoded, validated message from a peer.
    Message(Envelope),
    /// The link to `peer` came up (handshake done, first frame) or went down (closed, silent
    /// past the liveness timeout).
    Link { peer: NodeId, up: bool },
    /// Time passed: periodic work (steps, deadlines, status, liveness).
    Tick,
    /// The runtime's time-sync estimate after a beacon from the leader: offset of the node's
    /// host clock to the leader's and the estimate's error, ns (a negative error: not
    /// synchronized yet). The runtime has already corrected its clock by it.
    Sync { offset_ns: i64, error_ns: i64 },
    /// Messages the runtime could not deliver (queue full, link down, send timed out).
    Undelivered(u64),
    /// What this role's sensors delivered (a frame, a tag reading, …).
    Sensor(S),
}

/// A node core, driven by a runtime.
pub trait Node {
    /// What this role's sensors deliver; [`std::convert::Infallible`] for roles without any.
    type Sensor;

    fn id(&self) -> NodeId;

    /// Handle one input at cluster time `now`; returns the messages to send.
    fn handle(&mut self, now: ClusterTime, input: Input<Self::Sensor>) -> Vec<Outgoing>;
}
