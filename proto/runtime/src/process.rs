//! Driving one node core as an OS process: what every role's process shares, written once.
//!
//! [`run`] opens the node's transport and loops over one `select!`: shutdown, a tick every
//! [`ProcessConfig::tick`], the transport's events and the node's sensor stream. Each event
//! becomes one [`Input`] for the core at the process's cluster time ([`HostClock`]: the host
//! clock corrected by the leader's beacons, which the loop consumes and hands the core as
//! [`Input::Sync`]); what the core returns is sent with a bounded wait
//! ([`ProcessConfig::send_timeout`]), so a vanished peer never stalls the node, and what could
//! not be delivered is counted and told to the core ([`Input::Undelivered`]). An `Assignment`
//! of this node to a head makes sure the transport has a link to that head (TCP dials it). A
//! `NodeStatus` leaving the node carries the bytes its transport has sent (`bytes_sent`, which
//! only the runtime knows). A role adds its own work after each step through [`Hooks`] (the
//! server records; a camera switches capture).

use crate::clock::HostClock;
use crate::transport::{Delivery, Event, StatsSnapshot, TransportConfig, TransportError, open};
use futures_util::{Stream, StreamExt};
use proto::msg::Message;
use proto::node::{Input, Node, Outgoing};
use proto::{ClusterTime, NodeId};
use serde::Serialize;
use std::collections::BTreeMap;
use std::time::Duration;
use thiserror::Error;
use tokio_util::sync::CancellationToken;
use tracing::{debug, info, warn};

/// Longest a send may wait for room before it is counted as undelivered, by default.
pub const SEND_TIMEOUT: Duration = Duration::from_millis(20);

/// How many undelivered messages a run keeps the time of ([`RunSummary::undelivered_at`]): the
/// few a stop leaves, a crashed peer's flurry; beyond it only the counts grow.
pub const UNDELIVERED_TIMES_KEPT: usize = 256;

/// How to run one node process.
#[derive(Clone, Debug)]
pub struct ProcessConfig {
    pub transport: TransportConfig,
    /// The time leader whose beacons correct the clock (`None` for the leader itself).
    pub leader: Option<NodeId>,
    /// Period of [`Input::Tick`].
    pub tick: Duration,
    /// Longest a send may wait for room in a full queue.
    pub send_timeout: Duration,
}

impl ProcessConfig {
    /// `transport`, synchronized to `leader`, ticking every `tick`, sends waiting at most
    /// [`SEND_TIMEOUT`].
    pub fn new(transport: TransportConfig, leader: Option<NodeId>, tick: Duration) -> ProcessConfig {
        ProcessConfig {
            transport,
            leader,
            tick,
            send_timeout: SEND_TIMEOUT,
        }
    }
}

/// What a process's links did, returned when it stops.
#[derive(Clone, Debug, Default, PartialEq, Serialize)]
pub struct RunSummary {
    /// Messages from peers handed to the core.
    pub received: u64,
    /// Messages handed to the transport.
    pub sent: u64,
    /// Droppable messages that met a full queue.
    pub dropped: u64,
    /// Messages the transport refused (no link to the peer, shut down) or that waited past
    /// the send timeout.
    pub send_failures: u64,
    /// Links that went down.
    pub peers_down: u64,
    /// Messages not delivered (dropped or failed), by kind.
    pub undelivered: BTreeMap<&'static str, u64>,
    /// The same by recipient: a peer not up yet or gone (over iceoryx2 a frame for a node
    /// whose inbox has no reader is dropped at once) shows here.
    pub undelivered_to: BTreeMap<NodeId, u64>,
    /// When each of the first [`UNDELIVERED_TIMES_KEPT`] undelivered messages was sent, so a
    /// launch can tell the messages a cluster's stop leaves undelivered (to peers that stopped
    /// first) from losses during the run.
    pub undelivered_at: Vec<UndeliveredAt>,
    pub transport: StatsSnapshot,
}

/// One undelivered message: when it was sent (this node's cluster time), to whom, what.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct UndeliveredAt {
    pub at_ns: i64,
    pub to: NodeId,
    pub kind: &'static str,
}

/// Why a process stopped with an error.
#[derive(Debug, Error)]
pub enum RunError<E> {
    #[error("transport: {0}")]
    Transport(#[from] TransportError),
    /// The role's own work failed (the server's recording).
    #[error(transparent)]
    Node(E),
}

/// A role's own work around the shared loop.
pub trait Hooks<N> {
    type Error;
    /// Whether [`Hooks::after`] wants the messages that went out (the server records them);
    /// when false they are not kept.
    const KEEP_SENT: bool = false;

    /// After the core handled one input at `now` and its messages were sent (`sent`: those
    /// the transport took, when [`Hooks::KEEP_SENT`]). An error stops the process.
    ///
    /// # Errors
    /// Whatever the role's work cannot survive.
    fn after(&mut self, node: &mut N, now: ClusterTime, sent: &[Outgoing]) -> Result<(), Self::Error> {
        let _ = (node, now, sent);
        Ok(())
    }
}

/// After each step, tell a sensor thread whether the core wants its input (a camera's frames,
/// an acoustic node's audio): the node decides, the thread reads the flag before capturing.
pub struct SensorSwitch<N> {
    flag: std::sync::Arc<std::sync::atomic::AtomicBool>,
    wants: fn(&N) -> bool,
}

impl<N> SensorSwitch<N> {
    /// `wants` reads the node's wish; `flag` is shared with the sensor thread.
    pub fn new(flag: std::sync::Arc<std::sync::atomic::AtomicBool>, wants: fn(&N) -> bool) -> Self {
        SensorSwitch { flag, wants }
    }
}

impl<N> Hooks<N> for SensorSwitch<N> {
    type Error = std::convert::Infallible;

    fn after(&mut self, node: &mut N, _: ClusterTime, _: &[Outgoing]) -> Result<(), Self::Error> {
        self.flag
            .store((self.wants)(node), std::sync::atomic::Ordering::Relaxed);
        Ok(())
    }
}

/// No extra work.
#[derive(Debug, Default)]
pub struct NoHooks;

impl<N> Hooks<N> for NoHooks {
    type Error = std::convert::Infallible;
}

/// Run `node` until `shutdown` is cancelled, the transport closes, or a hook fails.
///
/// # Errors
/// The transport cannot open; a hook's error (the transport is shut down first).
pub async fn run<N, S, H>(
    node: &mut N,
    cfg: ProcessConfig,
    clock: HostClock,
    mut sensors: S,
    hooks: &mut H,
    shutdown: CancellationToken,
) -> Result<RunSummary, RunError<H::Error>>
where
    N: Node,
    S: Stream<Item = N::Sensor> + Unpin,
    H: Hooks<N>,
{
    let me = node.id();
    let (endpoint, mut inbox, stats, handle) = open(cfg.transport.clone()).await?;
    info!(node = %me, "running");
    let mut summary = RunSummary::default();
    // What could not be delivered is counted per message; the log says when, rate-limited (a
    // peer that stopped reading must not flood it).
    let mut undelivered_log = proto::log_limit::LogLimiter::default();
    let mut tick = tokio::time::interval(cfg.tick);
    tick.set_missed_tick_behavior(tokio::time::MissedTickBehavior::Skip);
    let mut sensors_open = true;
    let mut sent = Vec::new();
    let result = loop {
        let input = tokio::select! {
            () = shutdown.cancelled() => break Ok(()),
            _ = tick.tick() => Input::Tick,
            ev = inbox.recv() => match ev {
                None => {
                    warn!(node = %me, "transport closed");
                    break Ok(());
                }
                Some(Event::Message(m)) => {
                    summary.received += 1;
                    // Assigned to a head this node has no link to (TCP: it dials only the
                    // scenario's head at start): reach it now, before its priors come.
                    if let Message::Assignment(a) = &m.env.body
                        && a.node == me
                        && Some(m.from) == cfg.leader
                        && !endpoint.ensure_link(a.head)
                    {
                        warn!(node = %me, head = %a.head, "assigned to a head this node cannot reach");
                    }
                    match &m.env.body {
                        Message::SyncBeacon(b) if Some(m.from) == cfg.leader => {
                            match clock.observe(b.leader_time) {
                                Some((offset_ns, error_ns)) => Input::Sync { offset_ns, error_ns },
                                None => continue,
                            }
                        }
                        _ => Input::Message(m.env),
                    }
                }
                Some(Event::PeerUp(peer)) => {
                    debug!(node = %me, %peer, "peer up");
                    Input::Link { peer, up: true }
                }
                Some(Event::PeerDown(peer)) => {
                    summary.peers_down += 1;
                    warn!(node = %me, %peer, "peer down; counting what is lost");
                    Input::Link { peer, up: false }
                }
            },
            s = sensors.next(), if sensors_open => match s {
                Some(s) => Input::Sensor(s),
                None => {
                    info!(node = %me, "sensors ended");
                    sensors_open = false;
                    continue;
                }
            },
        };
        let now = clock.now();
        if matches!(input, Input::Tick) {
            // A flurry's tail: how many more were not delivered since its first line.
            for (_, more) in undelivered_log.overdue(now.0) {
                warn!(node = %me, more, "more messages not delivered since the last such line");
            }
        }
        let out = node.handle(now, input);
        sent.clear();
        let mut undelivered = 0;
        for mut o in out {
            // Only the runtime knows what went on the wire: a status carries it.
            if let Message::NodeStatus(s) = &mut o.body {
                s.bytes_sent = stats.bytes_sent.load(std::sync::atomic::Ordering::Relaxed);
            }
            let to = o.to;
            let kind = o.body.kind();
            let keep = H::KEEP_SENT.then(|| o.clone());
            let failed = match tokio::time::timeout(cfg.send_timeout, endpoint.send(o, now)).await {
                Ok(Ok(Delivery::Queued)) => {
                    summary.sent += 1;
                    sent.extend(keep);
                    None
                }
                Ok(Ok(Delivery::Dropped)) => {
                    summary.dropped += 1;
                    Some("dropped: the recipient's queue was full or nobody reads it".to_string())
                }
                Ok(Err(e)) => {
                    summary.send_failures += 1;
                    Some(format!("send failed: {e}"))
                }
                Err(_) => {
                    summary.send_failures += 1;
                    Some("send timed out".to_string())
                }
            };
            if let Some(why) = failed {
                undelivered += 1;
                *summary.undelivered.entry(kind).or_default() += 1;
                *summary.undelivered_to.entry(to).or_default() += 1;
                if summary.undelivered_at.len() < UNDELIVERED_TIMES_KEPT {
                    summary.undelivered_at.push(UndeliveredAt {
                        at_ns: now.0,
                        to,
                        kind,
                    });
                }
                if let Some(more) = undelivered_log.admit(now.0, "undelivered") {
                    warn!(node = %me, %to, kind, more, "{why}; not delivered");
                }
            }
        }
        if undelivered > 0 {
            // The core only counts these; it has nothing to say back.
            let _ = node.handle(now, Input::Undelivered(undelivered));
        }
        if let Err(e) = hooks.after(node, now, &sent) {
            break Err(RunError::Node(e));
        }
    };
    // A flurry at the stop: say how many followed its first line.
    for (_, more) in undelivered_log.overdue(i64::MAX) {
        warn!(node = %me, more, "more messages not delivered since the last such line");
    }
    summary.transport = stats.snapshot();
    handle.shutdown().await;
    info!(
        node = %me,
        sent = summary.sent,
        send_failures = summary.send_failures,
        dropped = summary.dropped,
        undelivered = ?summary.undelivered,
        undelivered_to = ?summary.undelivered_to,
        "stopped"
    );
    result.map(|()| summary)
}

/// A node without sensors (heads, the server).
pub fn no_sensors<T>() -> futures_util::stream::Pending<T> {
    futures_util::stream::pending()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::transport::{InProcessHub, TransportConfig};
    use proto::Role;
    use proto::msg::{Mode, NodeStatus};

    /// Sends a status to node 2 on every tick, its `bytes_sent` left at 0 as a core leaves it.
    struct Reporter;

    /// Sends a status to node 3, which no process is, on every tick.
    struct ToNobody;

    impl Node for ToNobody {
        type Sensor = std::convert::Infallible;

        fn id(&self) -> NodeId {
            NodeId(1)
        }

        fn handle(&mut self, now: ClusterTime, input: Input<Self::Sensor>) -> Vec<Outgoing> {
            let mut out = Reporter.handle(now, input);
            for o in &mut out {
                o.to = NodeId(3);
            }
            out
        }
    }

    impl Node for Reporter {
        type Sensor = std::convert::Infallible;

        fn id(&self) -> NodeId {
            NodeId(1)
        }

        fn handle(&mut self, _: ClusterTime, input: Input<Self::Sensor>) -> Vec<Outgoing> {
            if !matches!(input, Input::Tick) {
                return Vec::new();
            }
            let status = NodeStatus {
                mode: Mode::Active,
                time_in_mode_ns: [0; 3],
                frames: 0,
                detections: 0,
                dropped: 0,
                rejected: 0,
                sync_offset_ns: 0,
                sync_error_ns: -1,
                bytes_sent: 0,
            };
            vec![Outgoing::new(NodeId(2), Message::NodeStatus(status))]
        }
    }

    fn config(hub: &InProcessHub, me: u32) -> TransportConfig {
        TransportConfig::InProcess {
            hub: hub.clone(),
            me: NodeId(me),
            role: Role::Camera,
            queue_len: 16,
        }
    }

    /// Each status carries the bytes its node put on the wire before it: every frame so far.
    #[tokio::test]
    async fn a_status_carries_the_bytes_sent_before_it() {
        let hub = InProcessHub::new();
        let (_ep, mut inbox, _stats, receiver) = open(config(&hub, 2)).await.unwrap();
        let shutdown = CancellationToken::new();
        let cfg = ProcessConfig::new(config(&hub, 1), None, Duration::from_millis(5));
        let stop = shutdown.clone();
        let clock = HostClock::follower();
        let mut node = Reporter;
        let mut hooks = NoHooks;
        let sender = run(&mut node, cfg, clock, no_sensors(), &mut hooks, stop);
        let listen = async {
            let (mut seen, mut sizes) = (Vec::new(), Vec::new());
            while seen.len() < 4 {
                let ev = tokio::time::timeout(Duration::from_secs(10), inbox.recv())
                    .await
                    .unwrap();
                if let Some(Event::Message(m)) = ev
                    && let Message::NodeStatus(s) = &m.env.body
                {
                    sizes.push(proto::encode(&m.env).unwrap().len() as u64);
                    seen.push(s.bytes_sent);
                }
            }
            shutdown.cancel();
            (seen, sizes)
        };
        let (summary, (seen, sizes)) = tokio::join!(sender, listen);
        let summary = summary.unwrap();
        assert!(summary.transport.bytes_sent >= sizes.iter().sum::<u64>());
        // The first status went out before anything else; each later one counts the ones
        // before it.
        assert_eq!(seen[0], 0);
        for k in 1..seen.len() {
            assert_eq!(seen[k], sizes[..k].iter().sum::<u64>(), "{seen:?} {sizes:?}");
        }
        receiver.shutdown().await;
    }

    /// What could not be delivered is counted by kind and by recipient, so a run's drops can
    /// be told apart (a peer not up yet, one gone).
    #[tokio::test]
    async fn undelivered_messages_are_counted_by_kind_and_recipient() {
        let hub = InProcessHub::new();
        let (_ep, _inbox, _stats, receiver) = open(config(&hub, 2)).await.unwrap();
        let shutdown = CancellationToken::new();
        let cfg = ProcessConfig::new(config(&hub, 1), None, Duration::from_millis(5));
        let stop = shutdown.clone();
        let (mut node, mut hooks) = (ToNobody, NoHooks);
        let sender = run(
            &mut node,
            cfg,
            HostClock::follower(),
            no_sensors(),
            &mut hooks,
            stop,
        );
        let cancel = async {
            tokio::time::sleep(Duration::from_millis(100)).await;
            shutdown.cancel();
        };
        let (summary, ()) = tokio::join!(sender, cancel);
        let summary = summary.unwrap();
        let n = summary.undelivered.get("node_status").copied().unwrap_or(0);
        assert!(n > 0, "{summary:?}");
        assert_eq!(summary.undelivered_to.get(&NodeId(3)), Some(&n), "{summary:?}");
        assert_eq!(summary.undelivered_to.len(), 1);
        let kept = summary.undelivered_at.len();
        assert_eq!(kept as u64, n.min(UNDELIVERED_TIMES_KEPT as u64), "{summary:?}");
        assert!(
            summary
                .undelivered_at
                .iter()
                .all(|u| u.to == NodeId(3) && u.kind == "node_status")
        );
        assert!(
            summary
                .undelivered_at
                .windows(2)
                .all(|w| w[0].at_ns <= w[1].at_ns)
        );
        assert_eq!(summary.sent, 0);
        receiver.shutdown().await;
    }
}
