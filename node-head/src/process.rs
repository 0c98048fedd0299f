//! The head process: [`HeadNode`] driven by tokio over a `runtime::transport` link.
//!
//! One loop `select!`s over three events: a tick every [`TICK_MS`] with the cluster time, a
//! transport event (a message, a peer up or down), and shutdown. Everything the core returns
//! is sent with a bounded wait, so a vanished camera or server never stalls the loop: the head
//! keeps stepping, predicting and counting (failed and timed-out sends are counted, peers that
//! drop are reported to the core as down). Cluster time is the host's UNIX time corrected by a
//! [`SyncEstimator`] over the server's `SyncBeacon`s; every [`STATUS_PERIOD_MS`] the head sends
//! the server a `NodeStatus` with that estimate's offset and error.

use crate::config::{ConfigError, HeadConfig};
use crate::head::HeadNode;
use crate::stats::Counters;
use proto::msg::{Message, Mode, NodeStatus};
use proto::node::Outgoing;
use proto::scenario::{NodeRole, Scenario, TransportKind};
use proto::sync::SyncEstimator;
use proto::{ClusterTime, NodeId, Role};
use runtime::transport::{Event, IpcConfig, TcpConfig, TransportConfig, TransportError, open};
use std::net::SocketAddr;
use std::sync::Arc;
use std::sync::Mutex;
use std::time::Duration;
use thiserror::Error;
use tokio_util::sync::CancellationToken;
use tracing::{info, warn};

/// Tick period of the loop, ms: fine enough for step starts and deadlines.
pub const TICK_MS: u64 = 5;
/// Longest a send may wait for room before it is counted as failed.
pub const SEND_TIMEOUT_MS: u64 = 20;
/// How often the head tells the server its sync estimate and failures in a `NodeStatus`, ms.
pub const STATUS_PERIOD_MS: u64 = 1000;

/// What the process needs.
#[derive(Clone, Debug)]
pub struct ProcessConfig {
    pub scenario: Scenario,
    pub id: u32,
    pub transport: TransportKind,
    /// Override the scenario's listen address (TCP), e.g. port 0 in tests.
    pub listen: Option<SocketAddr>,
}

/// Why the head process could not run.
#[derive(Debug, Error)]
pub enum ProcessError {
    #[error(transparent)]
    Config(#[from] ConfigError),
    #[error("transport: {0}")]
    Transport(#[from] TransportError),
    #[error("bad address {addr:?} for node {node}: {problem}")]
    Address {
        node: u32,
        addr: String,
        problem: String,
    },
}

/// What the process did, returned at shutdown.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Summary {
    pub counters: Counters,
    pub sent: u64,
    pub send_failures: u64,
    pub peers_down: u64,
}

/// Cluster time: host UNIX time corrected by the offset and drift a [`SyncEstimator`] fits over
/// the server's beacons (the host time itself before the first beacon).
#[derive(Debug, Default)]
pub struct Clock {
    sync: Mutex<SyncEstimator>,
}

impl Clock {
    // The runtime owns the clock; node cores never read it.
    #[allow(clippy::disallowed_methods)]
    fn host_ns() -> i64 {
        ClusterTime::wall_clock().0
    }

    fn estimator(&self) -> std::sync::MutexGuard<'_, SyncEstimator> {
        self.sync.lock().unwrap_or_else(|p| p.into_inner())
    }

    pub fn now(&self) -> ClusterTime {
        let host = Self::host_ns();
        self.estimator().to_cluster(host).unwrap_or(ClusterTime(host))
    }

    /// Feed a beacon just received from the leader.
    pub fn sync(&self, leader: ClusterTime) {
        if let Err(e) = self.estimator().observe(Self::host_ns(), leader) {
            tracing::debug!(error = %e, "sync beacon not used");
        }
    }

    /// The estimate as a `NodeStatus` carries it: offset to the leader and sync error, ns
    /// (error −1 before the first beacon).
    pub fn estimate(&self) -> (i64, i64) {
        let host = Self::host_ns();
        let s = self.estimator();
        (
            s.offset_ns(host),
            s.prediction_error_ns().map_or(-1, |e| e.round() as i64),
        )
    }
}

fn parse_addr(node: u32, addr: &str) -> Result<SocketAddr, ProcessError> {
    addr.parse()
        .map_err(|e: std::net::AddrParseError| ProcessError::Address {
            node,
            addr: addr.into(),
            problem: e.to_string(),
        })
}

fn transport_config(cfg: &ProcessConfig, clock: Arc<Clock>) -> Result<TransportConfig, ProcessError> {
    let s = &cfg.scenario;
    let me = NodeId(cfg.id);
    Ok(match cfg.transport {
        TransportKind::Ipc => {
            let mut c = IpcConfig::new(s.network.domain.clone(), me, Role::Head, s.nodes.len());
            c.queue_len = s.network.queue_len.max(1);
            c.heartbeat = Some((
                Duration::from_millis(s.network.heartbeat_ms.max(1)),
                Arc::new(move || clock.now()),
            ));
            TransportConfig::Ipc(c)
        }
        TransportKind::Tcp => {
            let mut c = TcpConfig::new(me, Role::Head);
            c.listen = match (cfg.listen, s.node(cfg.id).and_then(|n| n.listen.as_deref())) {
                (Some(a), _) => Some(a),
                (None, Some(a)) => Some(parse_addr(cfg.id, a)?),
                (None, None) => None,
            };
            // Heads dial the server; cameras dial their head.
            if let Some(server) = s.nodes.iter().find(|n| n.role == NodeRole::Server)
                && let Some(addr) = &server.listen
            {
                c.peers.insert(NodeId(server.id), parse_addr(server.id, addr)?);
            }
            c.heartbeat = Duration::from_millis(s.network.heartbeat_ms.max(1));
            c.liveness_timeout = Duration::from_millis(s.network.liveness_timeout_ms.max(1));
            c.queue_len = s.network.queue_len.max(1);
            c.clock = Arc::new(move || clock.now());
            TransportConfig::Tcp(c)
        }
    })
}

/// Run head `cfg.id` until `shutdown` is cancelled or the transport closes.
///
/// # Errors
/// The scenario has no such head, an address does not parse, or the transport cannot open.
pub async fn run(cfg: ProcessConfig, shutdown: CancellationToken) -> Result<Summary, ProcessError> {
    let head_cfg = HeadConfig::from_scenario(&cfg.scenario, cfg.id)?;
    let clock = Arc::new(Clock::default());
    let transport = transport_config(&cfg, clock.clone())?;
    info!(head = cfg.id, transport = ?cfg.transport, "head starting");
    run_on(head_cfg, transport, clock, shutdown).await
}

/// The head's `NodeStatus`: always Active since it started, its send failures and rejected
/// messages, and its sync estimate.
fn status(clock: &Clock, started: ClusterTime, head: &HeadNode, summary: &Summary) -> NodeStatus {
    let (sync_offset_ns, sync_error_ns) = clock.estimate();
    NodeStatus {
        mode: Mode::Active,
        time_in_mode_ns: [u64::try_from(clock.now() - started).unwrap_or(0), 0, 0],
        frames: 0,
        detections: 0,
        dropped: summary.send_failures,
        rejected: head.counters().rejected,
        sync_offset_ns,
        sync_error_ns,
    }
}

/// Run a head on an explicit transport (the in-process hub in tests).
///
/// # Errors
/// The transport cannot open.
pub async fn run_on(
    head_cfg: HeadConfig,
    transport: TransportConfig,
    clock: Arc<Clock>,
    shutdown: CancellationToken,
) -> Result<Summary, ProcessError> {
    let server = head_cfg.server;
    let me = head_cfg.id;
    let mut head = HeadNode::new(head_cfg);
    let (endpoint, mut inbox, _stats, handle) = open(transport).await?;
    info!(head = %me, "head running");
    let mut summary = Summary::default();
    let mut interval = tokio::time::interval(Duration::from_millis(TICK_MS));
    interval.set_missed_tick_behavior(tokio::time::MissedTickBehavior::Skip);
    let mut status_every = tokio::time::interval(Duration::from_millis(STATUS_PERIOD_MS));
    status_every.set_missed_tick_behavior(tokio::time::MissedTickBehavior::Skip);
    let started = clock.now();
    loop {
        let out: Vec<Outgoing> = tokio::select! {
            () = shutdown.cancelled() => break,
            _ = interval.tick() => head.tick(clock.now()),
            _ = status_every.tick(), if server.is_some() => {
                let status = status(&clock, started, &head, &summary);
                server.map(|s| Outgoing::new(s, Message::NodeStatus(status))).into_iter().collect()
            }
            ev = inbox.recv() => match ev {
                None => {
                    warn!("transport closed; head stops");
                    break;
                }
                Some(Event::Message(inc)) => {
                    if let Message::SyncBeacon(b) = &inc.env.body
                        && Some(inc.from) == server
                    {
                        clock.sync(b.leader_time);
                    }
                    head.on_message(clock.now(), inc.env)
                }
                Some(Event::PeerDown(n)) => {
                    summary.peers_down += 1;
                    warn!(peer = %n, "peer down; tracking goes on");
                    head.node_liveness(clock.now(), n, false)
                }
                Some(Event::PeerUp(n)) => head.node_liveness(clock.now(), n, true),
            },
        };
        for o in out {
            let to = o.to;
            let sent = tokio::time::timeout(
                Duration::from_millis(SEND_TIMEOUT_MS),
                endpoint.send(o, clock.now()),
            )
            .await;
            match sent {
                Ok(Ok(_)) => summary.sent += 1,
                Ok(Err(e)) => {
                    summary.send_failures += 1;
                    tracing::debug!(to = %to, error = %e, "send failed");
                }
                Err(_) => {
                    summary.send_failures += 1;
                    tracing::debug!(to = %to, "send timed out");
                }
            }
        }
    }
    summary.counters = *head.counters();
    info!(
        steps = summary.counters.steps,
        applied = summary.counters.applied,
        late = summary.counters.late,
        send_failures = summary.send_failures,
        "head stopping"
    );
    handle.shutdown().await;
    Ok(summary)
}
