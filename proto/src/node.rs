//! What every sans-IO node core emits: messages addressed to a node id. Runtimes (process or
//! simulation) own the links and deliver them; cores never touch IO or clocks.

use crate::ids::NodeId;
use crate::msg::Message;

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
