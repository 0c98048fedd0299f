//! The server as an OS process: the [`ServerNode`] core driven by `runtime::process::run`, with
//! every input, decision and sent frame (but the viewers' updates) appended to the recording
//! after each step.
//!
//! The server is the time leader, so its cluster time is its wall clock (ns since the Unix
//! epoch): continuous across restarts. On start it opens the recording; if the file exists it
//! replays it ([`ServerNode::restore`]) to rebuild membership, global ids and last posteriors,
//! gives every known node a reconnection grace ([`ServerNode::resume`]) and appends from there.
//! A recording that fails stops the server: nothing may be lost silently.

use crate::core::{RestoreStats, ServerConfig, ServerNode};
use crate::record::{Origin, Record, Stamped};
use crate::recording::{Recorder, RecordingError};
use proto::msg::Message;
use proto::node::Outgoing;
use proto::scenario::Scenario;
use proto::{ClusterTime, Envelope, NodeId};
use runtime::process::no_sensors;
use runtime::transport::{TransportConfig, TransportError};
use runtime::{Hooks, HostClock, RunError, RunSummary};
use std::path::PathBuf;
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
    /// What a new recording says of the run's clock and truth (`ocelli launch` knows it; a
    /// real deployment's server records none, so its report scores nothing).
    pub origin: Option<Origin>,
}

/// Why the server process stopped with an error.
#[derive(Debug, Error)]
pub enum ProcessError {
    #[error(transparent)]
    Recording(#[from] RecordingError),
    #[error("transport: {0}")]
    Transport(#[from] TransportError),
}

/// What a run did.
#[derive(Clone, Debug, Default)]
pub struct Summary {
    pub restored: Option<RestoreStats>,
    pub records: u64,
    pub run: RunSummary,
}

/// Open the recording and build the core, resuming from the recording if it has records. A
/// new recording starts with the scenario and, when known, the run's [`Origin`].
///
/// # Errors
/// A recording that cannot be opened or read.
pub fn start(
    cfg: &ProcessConfig,
    now: ClusterTime,
) -> Result<(ServerNode, Recorder, Option<RestoreStats>), ProcessError> {
    let (scenario, id) = (&cfg.scenario, cfg.id);
    let (mut rec, back) = Recorder::open(&cfg.record, &scenario.name)?;
    let server_cfg = ServerConfig::from_scenario(scenario.clone(), id);
    if back.records.is_empty() {
        rec.append(&Stamped::new(now, Record::Scenario(scenario.to_toml())))?;
        if let Some(origin) = cfg.origin {
            rec.append(&Stamped::new(now, Record::Origin(origin)))?;
        }
        return Ok((ServerNode::new(server_cfg), rec, None));
    }
    let cfg = server_cfg;
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

/// After each step: the core's journal, then the frames it sent, into the recording; the
/// recording synced to disk every `sync_every`.
struct Recording {
    rec: Recorder,
    records: u64,
    sync_every_ns: i64,
    last_sync: Option<ClusterTime>,
    syncs: u64,
}

impl Hooks<ServerNode> for Recording {
    type Error = RecordingError;
    const KEEP_SENT: bool = true;

    fn after(
        &mut self,
        node: &mut ServerNode,
        now: ClusterTime,
        sent: &[Outgoing],
    ) -> Result<(), RecordingError> {
        for r in node.take_records() {
            self.rec.append(&r)?;
            self.records += 1;
        }
        // A viewer's updates follow from what is recorded; recording them too would grow the
        // recording with every viewer.
        for o in sent.iter().filter(|o| !matches!(o.body, Message::ViewUpdate(_))) {
            // The transport stamps the per-link sequence number; it is not known here.
            let env = Envelope {
                source: node.id(),
                seq: 0,
                time: now,
                body: o.body.clone(),
            };
            if let Err(e) = self
                .rec
                .append(&Stamped::new(now, Record::Sent { to: o.to, env }))
            {
                tracing::warn!(error = %e, "sent frame not recorded");
            }
            self.records += 1;
        }
        if self.last_sync.is_none_or(|t| now - t >= self.sync_every_ns) {
            self.rec.sync()?;
            self.last_sync = Some(now);
            self.syncs += 1;
            if self.syncs.is_multiple_of(20) {
                log_status(node);
            }
        }
        Ok(())
    }
}

/// Run the server until `shutdown` is cancelled.
///
/// # Errors
/// The recording or the transport failing; a failing recording stops the server (nothing may
/// be lost silently).
pub async fn run(cfg: ProcessConfig, shutdown: CancellationToken) -> Result<Summary, ProcessError> {
    let clock = HostClock::leader();
    let (mut node, rec, restored) = start(&cfg, clock.now())?;
    tracing::info!(id = %cfg.id, record = %cfg.record.display(), "server starting");
    let mut recording = Recording {
        rec,
        records: 0,
        sync_every_ns: i64::try_from(cfg.sync_every.as_nanos()).unwrap_or(i64::MAX),
        last_sync: None,
        syncs: 0,
    };
    let process = runtime::ProcessConfig::new(cfg.transport.clone(), None, cfg.tick);
    let result = runtime::run(&mut node, process, clock, no_sensors(), &mut recording, shutdown).await;
    // Whatever ended the run, what was recorded reaches the disk.
    let synced = recording.rec.sync();
    let run = match result {
        Ok(run) => run,
        Err(RunError::Transport(e)) => return Err(e.into()),
        Err(RunError::Node(e)) => return Err(e.into()),
    };
    synced?;
    tracing::info!(received = run.received, sent = run.sent, "server stopped");
    Ok(Summary {
        restored,
        records: recording.records,
        run,
    })
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
        worst_sync_ms = worst_sync_ms.unwrap_or(-1.0),
        "server status"
    );
}
