//! In-process transport: a hub of tokio channels keyed by node id, for tests and
//! single-process use. Frames still go through `encode`/`decode`, so what passes here passes
//! the wire. (The deterministic simulation runtime has its own virtual network.)

use super::common::{accept, deliver};
use super::stats::{TransportStats, bump};
use super::{Delivery, Event, OutFrame, SendError, TransportError};
use proto::ids::NodeId;
use std::collections::HashMap;
use std::sync::{Arc, Mutex};
use tokio::sync::mpsc;

type Slot = (mpsc::Sender<Event>, Arc<TransportStats>);

/// The shared switchboard. Clone it into every endpoint of the process.
#[derive(Clone, Default)]
pub struct InProcessHub {
    nodes: Arc<Mutex<HashMap<NodeId, Slot>>>,
}

impl std::fmt::Debug for InProcessHub {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("InProcessHub").finish_non_exhaustive()
    }
}

impl InProcessHub {
    pub fn new() -> Self {
        Self::default()
    }

    fn lock(&self) -> std::sync::MutexGuard<'_, HashMap<NodeId, Slot>> {
        self.nodes.lock().unwrap_or_else(|p| p.into_inner())
    }

    pub(crate) fn register(
        &self,
        me: NodeId,
        tx: mpsc::Sender<Event>,
        stats: Arc<TransportStats>,
    ) -> Result<(), TransportError> {
        let peers: Vec<Slot> = {
            let mut nodes = self.lock();
            if nodes.contains_key(&me) {
                return Err(TransportError::Config(format!(
                    "node {me} is already on this hub"
                )));
            }
            let peers = nodes.values().cloned().collect();
            nodes.insert(me, (tx.clone(), stats.clone()));
            peers
        };
        // Everyone already on the hub sees the newcomer come up, and it sees them.
        for (ptx, pstats) in peers {
            if ptx.try_send(Event::PeerUp(me)).is_ok() {
                bump(&pstats.peers_up);
            }
        }
        let others: Vec<NodeId> = self.lock().keys().copied().filter(|&n| n != me).collect();
        for n in others {
            if tx.try_send(Event::PeerUp(n)).is_ok() {
                bump(&stats.peers_up);
            }
        }
        Ok(())
    }

    pub(crate) fn unregister(&self, me: NodeId) {
        let peers: Vec<Slot> = {
            let mut nodes = self.lock();
            nodes.remove(&me);
            nodes.values().cloned().collect()
        };
        for (ptx, pstats) in peers {
            if ptx.try_send(Event::PeerDown(me)).is_ok() {
                bump(&pstats.peers_lost);
            }
        }
    }

    pub(crate) async fn deliver(
        &self,
        from: NodeId,
        frame: OutFrame,
        _sender_stats: &TransportStats,
    ) -> Result<Delivery, SendError> {
        let slot = self.lock().get(&frame.to).cloned();
        let Some((tx, stats)) = slot else {
            return Err(SendError::UnknownPeer(frame.to));
        };
        match accept(&frame.bytes, &stats, Some(from), "in-process") {
            Some(env) => deliver(&tx, from, env, &stats).await,
            // Rejected by the receiver: counted there; the sender's frame did leave.
            None => Ok(Delivery::Queued),
        }
    }
}

#[cfg(test)]
pub(crate) mod tests {
    use super::super::{Delivery, Event, TransportConfig, open};
    use super::*;
    use proto::msg::{Command, Message, Mode};
    use proto::node::Outgoing;
    use proto::time::ClusterTime;
    use proto::{MAX_FRAME_BYTES, PROTOCOL_VERSION, Role};

    fn cfg(hub: &InProcessHub, me: u32, queue_len: usize) -> TransportConfig {
        TransportConfig::InProcess {
            hub: hub.clone(),
            me: NodeId(me),
            role: Role::Tool,
            queue_len,
        }
    }

    fn command(n: u32) -> Message {
        Message::Command(Command {
            node: NodeId(n),
            mode: Mode::Active,
        })
    }

    /// A droppable message: the wire contract's measurement fixture.
    pub(crate) fn measurement() -> Message {
        proto::examples::messages()[3].body.clone()
    }

    #[tokio::test]
    async fn delivers_in_order_with_source_seq_and_time() {
        let hub = InProcessHub::new();
        let (a, _ia, sa, _ha) = open(cfg(&hub, 1, 64)).await.unwrap();
        let (_b, mut ib, sb, _hb) = open(cfg(&hub, 2, 64)).await.unwrap();
        for k in 0..10 {
            let d = a
                .send(Outgoing::new(NodeId(2), command(k)), ClusterTime(100 + k as i64))
                .await;
            assert_eq!(d, Ok(Delivery::Queued));
        }
        let mut got = Vec::new();
        while got.len() < 10 {
            match ib.recv().await.unwrap() {
                Event::Message(m) => got.push(m),
                Event::PeerUp(n) => assert_eq!(n, NodeId(1)),
                Event::PeerDown(n) => panic!("unexpected PeerDown({n})"),
            }
        }
        for (k, m) in got.iter().enumerate() {
            assert_eq!(m.from, NodeId(1));
            assert_eq!(m.env.seq, k as u64);
            assert_eq!(m.env.time, ClusterTime(100 + k as i64));
            assert_eq!(m.env.body, command(k as u32));
        }
        assert_eq!(sa.snapshot().sent, 10);
        assert_eq!(sb.snapshot().received, 10);
    }

    #[tokio::test]
    async fn full_inbox_drops_measurements_but_never_commands() {
        let hub = InProcessHub::new();
        let (a, _ia, _sa, _ha) = open(cfg(&hub, 1, 64)).await.unwrap();
        // Node 2's inbox holds 4 events; nobody reads it. It already holds PeerUp(1).
        let (_b, mut ib, sb, _hb) = open(cfg(&hub, 2, 4)).await.unwrap();
        let mut dropped = 0;
        for _ in 0..10 {
            if a.send(Outgoing::new(NodeId(2), measurement()), ClusterTime(0))
                .await
                .unwrap()
                == Delivery::Dropped
            {
                dropped += 1;
            }
        }
        assert_eq!(dropped, 7, "3 fit after PeerUp, 7 dropped");
        assert_eq!(sb.snapshot().dropped_inbox_full, 7);
        // A command on the full inbox waits until the reader makes room, then arrives.
        let sender = tokio::spawn({
            let a = a.clone();
            async move { a.send(Outgoing::new(NodeId(2), command(9)), ClusterTime(0)).await }
        });
        let mut kinds = Vec::new();
        for _ in 0..5 {
            match ib.recv().await.unwrap() {
                Event::Message(m) => kinds.push(m.env.body.kind()),
                Event::PeerUp(_) => kinds.push("peer_up"),
                Event::PeerDown(_) => kinds.push("peer_down"),
            }
        }
        assert_eq!(sender.await.unwrap(), Ok(Delivery::Queued));
        assert_eq!(
            kinds,
            vec!["peer_up", "measurement", "measurement", "measurement", "command"]
        );
        assert_eq!(sb.snapshot().dropped_inbox_full, 7);
    }

    #[tokio::test]
    async fn garbage_and_unknown_peers_are_counted_not_delivered() {
        let hub = InProcessHub::new();
        let (a, _ia, sa, _ha) = open(cfg(&hub, 1, 64)).await.unwrap();
        let (_b, mut ib, sb, _hb) = open(cfg(&hub, 2, 64)).await.unwrap();
        a.send_raw_frame(NodeId(2), vec![PROTOCOL_VERSION as u8, 0xff, 0xff, 0xff])
            .await
            .unwrap();
        a.send_raw_frame(NodeId(2), vec![0; MAX_FRAME_BYTES + 1])
            .await
            .unwrap();
        a.send_raw_frame(NodeId(2), vec![9]).await.unwrap();
        let e = a.send(Outgoing::new(NodeId(7), command(1)), ClusterTime(0)).await;
        assert_eq!(e, Err(SendError::UnknownPeer(NodeId(7))));
        a.send(Outgoing::new(NodeId(2), command(3)), ClusterTime(0))
            .await
            .unwrap();
        let s = sb.snapshot();
        assert_eq!(
            (s.rejected_malformed, s.rejected_oversized, s.rejected_version),
            (1, 1, 1)
        );
        assert_eq!(sa.snapshot().unroutable, 1);
        assert_eq!(ib.recv().await, Some(Event::PeerUp(NodeId(1))));
        match ib.recv().await {
            Some(Event::Message(m)) => assert_eq!(m.env.body, command(3)),
            other => panic!("expected the command, got {other:?}"),
        }
    }

    #[tokio::test]
    async fn shutdown_unregisters_and_tells_peers() {
        let hub = InProcessHub::new();
        let (_a, mut ia, _sa, _ha) = open(cfg(&hub, 1, 64)).await.unwrap();
        let (_b, _ib, _sb, hb) = open(cfg(&hub, 2, 64)).await.unwrap();
        assert!(open(cfg(&hub, 1, 64)).await.is_err(), "duplicate id accepted");
        hb.shutdown().await;
        assert_eq!(ia.recv().await, Some(Event::PeerUp(NodeId(2))));
        assert_eq!(ia.recv().await, Some(Event::PeerDown(NodeId(2))));
        let (_b2, _ib2, _sb2, _hb2) = open(cfg(&hub, 2, 64)).await.unwrap();
    }
}
