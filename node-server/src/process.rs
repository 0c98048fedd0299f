//! The server process: the [`ServerNode`] core driven by tokio, a transport and the wall clock,
//! with every input, decision and sent frame appended to the recording.
//!
//! The server is the time leader, so its cluster time is its wall clock (ns since the Unix
//! epoch): continuous across restarts. On start it opens the recording; if the file exists it
//! replays it ([`ServerNode::restore`]) to rebuild membership, global ids and last posteriors,
//! gives every known node a reconnection grace ([`ServerNode::resume`]) and appends from there.
//!
//! One event loop `select!`s over shutdown, the transport's inbox, the tick timer and the
//! recording's `sync_data` timer.

use crate::core::{RestoreStats, ServerConfig, ServerNode};
use crate::record::{Record, Stamped};
use crate::recording::{Recorder, RecordingError};
use proto::scenario::{Scenario, TransportKind};
use proto::transport::{
    Event, IpcConfig, TcpConfig, TransportConfig, TransportError, open as open_transport,
};
use proto::{ClusterTime, Envelope, NodeId, Role};
use std::path::PathBuf;
use std::sync::Arc;
use std::time::Duration;
use thiserror::Error;
use tokio_util::sync::CancellationToken;

/// How to run the server process.
#[derive(Clone, Debug)]
pub struct ProcessConfig {
    pub scenario: Scenario,
    pub id: NodeId,
    pub transport: TransportConfig,
    pub record: PathBuf,
    /// Period of [`ServerNode::tick`].
    pub tick: Duration,
    /// Period of `sync_data` on the recording.
    pub sync_every: Duration,
}

/// Why the server process stopped with an error.
#[derive(Debug, Error)]
pub enum ProcessError {
    #[error(transparent)]
    Recording(#[from] RecordingError),
    #[error("transport: {0}")]
    Transport(#[from] TransportError),
    #[error("scenario: {0}")]
    Config(String),
}

/// What a run did.
#[derive(Clone, Debug, Default)]
pub struct RunSummary {
    pub restored: Option<RestoreStats>,
    pub received: u64,
    pub sent: u64,
    pub send_failures: u64,
    pub records: u64,
}

/// The wall clock as cluster time (the leader's time base).
#[allow(clippy::disallowed_methods)] // the process runtime owns the clock
pub fn wall_now() -> ClusterTime {
    ClusterTime::wall_clock()
}

/// The transport configuration the scenario asks for.
///
/// # Errors
/// A server without a valid `listen` address for TCP.
pub fn transport_for(
    scenario: &Scenario,
    id: NodeId,
    kind: TransportKind,
) -> Result<TransportConfig, ProcessError> {
    let net = &scenario.network;
    Ok(match kind {
        TransportKind::Tcp => {
            let listen = scenario
                .node(id.0)
                .and_then(|n| n.listen.as_deref())
                .ok_or_else(|| ProcessError::Config(format!("server {id} has no `listen` address")))?;
            let listen = listen
                .parse()
                .map_err(|e| ProcessError::Config(format!("server {id} listen `{listen}`: {e}")))?;
            let mut c = TcpConfig::new(id, Role::Server);
            c.listen = Some(listen);
            c.heartbeat = Duration::from_millis(net.heartbeat_ms);
            c.liveness_timeout = Duration::from_millis(net.liveness_timeout_ms);
            c.queue_len = net.queue_len;
            c.clock = Arc::new(wall_now);
            TransportConfig::Tcp(c)
        }
        TransportKind::Ipc => {
            let mut c = IpcConfig::new(net.domain.clone(), id, Role::Server, scenario.nodes.len());
            c.queue_len = net.queue_len;
            c.heartbeat = Some((Duration::from_millis(net.heartbeat_ms.max(1)), Arc::new(wall_now)));
            TransportConfig::Ipc(c)
        }
    })
}

/// Open the recording and build the core, resuming from the recording if it has records.
///
/// # Errors
/// A recording that cannot be opened or read.
pub fn start(
    scenario: &Scenario,
    id: NodeId,
    path: &std::path::Path,
    now: ClusterTime,
) -> Result<(ServerNode, Recorder, Option<RestoreStats>), ProcessError> {
    let (mut rec, back) = Recorder::open(path, &scenario.name)?;
    let cfg = ServerConfig::from_scenario(scenario.clone(), id);
    if back.records.is_empty() {
        rec.append(&Stamped::new(now, Record::Scenario(scenario.to_toml())))?;
        return Ok((ServerNode::new(cfg), rec, None));
    }
    let (mut node, stats) = ServerNode::restore(cfg, &back.records);
    let skipped = back.skipped_bytes();
    tracing::info!(
        records = back.records.len(),
        skipped_bytes = skipped,
        skipped_stretches = back.skipped.len(),
        decisions_matched = stats.decisions_matched,
        decisions_mismatched = stats.decisions_mismatched,
        "resumed from recording"
    );
    node.resume(now, back.records.len() as u64, skipped);
    for r in node.take_records() {
        rec.append(&r)?;
    }
    rec.sync()?;
    Ok((node, rec, Some(stats)))
}

/// Run the server until `shutdown` is cancelled.
///
/// # Errors
/// The recording or the transport failing; a failing recording stops the server (nothing may
/// be lost silently).
pub async fn run(cfg: ProcessConfig, shutdown: CancellationToken) -> Result<RunSummary, ProcessError> {
    let (mut node, mut rec, restored) = start(&cfg.scenario, cfg.id, &cfg.record, wall_now())?;
    let (endpoint, mut inbox, _stats, handle) = open_transport(cfg.transport.clone()).await?;
    tracing::info!(id = %cfg.id, record = %cfg.record.display(), addr = ?endpoint.local_addr(), "server running");
    let mut summary = RunSummary {
        restored,
        ..RunSummary::default()
    };
    let mut tick = tokio::time::interval(cfg.tick);
    tick.set_missed_tick_behavior(tokio::time::MissedTickBehavior::Delay);
    let mut sync = tokio::time::interval(cfg.sync_every);
    sync.set_missed_tick_behavior(tokio::time::MissedTickBehavior::Delay);
    let mut syncs = 0u64;
    let result = loop {
        let out = tokio::select! {
            biased;
            () = shutdown.cancelled() => break Ok(()),
            ev = inbox.recv() => {
                let now = wall_now();
                match ev {
                    Some(Event::Message(inc)) => {
                        summary.received += 1;
                        (now, node.on_message(now, inc.env))
                    }
                    Some(Event::PeerUp(n)) => (now, node.on_link(now, n, true)),
                    Some(Event::PeerDown(n)) => (now, node.on_link(now, n, false)),
                    None => break Ok(()),
                }
            }
            _ = tick.tick() => {
                let now = wall_now();
                (now, node.tick(now))
            }
            _ = sync.tick() => {
                if let Err(e) = rec.sync() {
                    break Err(e.into());
                }
                syncs += 1;
                if syncs.is_multiple_of(20) {
                    log_status(&node);
                }
                continue;
            }
        };
        let (now, out) = out;
        if let Err(e) = flush(&mut node, &mut rec, &mut summary) {
            break Err(e);
        }
        for o in out {
            let to = o.to;
            let body = o.body.clone();
            match endpoint.send(o, now).await {
                Ok(_) => {
                    summary.sent += 1;
                    // The transport stamps the per-link sequence number; it is not known here.
                    let env = Envelope {
                        source: cfg.id,
                        seq: 0,
                        time: now,
                        body,
                    };
                    if let Err(e) = rec.append(&Stamped::new(now, Record::Sent { to, env })) {
                        tracing::warn!(error = %e, "sent frame not recorded");
                    }
                    summary.records += 1;
                }
                Err(e) => {
                    summary.send_failures += 1;
                    tracing::debug!(%to, error = %e, "send failed");
                }
            }
        }
    };
    let synced = rec.sync();
    handle.shutdown().await;
    result?;
    synced?;
    tracing::info!(received = summary.received, sent = summary.sent, "server stopped");
    Ok(summary)
}

fn flush(node: &mut ServerNode, rec: &mut Recorder, summary: &mut RunSummary) -> Result<(), ProcessError> {
    for r in node.take_records() {
        rec.append(&r)?;
        summary.records += 1;
    }
    Ok(())
}

/// Membership, tracks and the worst visible sync error, for the operator.
fn log_status(node: &ServerNode) {
    let up = node.membership().members().filter(|(_, m)| m.up).count();
    let worst_sync_ms = node
        .sync_errors()
        .iter()
        .map(|(_, e)| *e as f64 * 1e-6)
        .fold(None, |a: Option<f64>, e| Some(a.map_or(e, |a| a.max(e))));
    tracing::info!(
        nodes_up = up,
        tracks = node.globals().count(),
        handovers = node.counters().handovers,
        rejected = node.counters().rejected,
        worst_sync_ms = ?worst_sync_ms,
        "server status"
    );
}
