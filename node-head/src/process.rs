//! The head as an OS process: [`HeadNode`] driven by `runtime::process::run` over a transport,
//! its cluster time the host clock corrected by the server's sync beacons. Sends wait a
//! bounded time, so a vanished camera or server never stalls stepping; a peer whose link drops
//! is reported to the core as down.

use crate::config::{ConfigError, HeadConfig};
use crate::head::HeadNode;
use crate::stats::Counters;
use proto::NodeId;
use runtime::process::no_sensors;
use runtime::{HostClock, NoHooks, RunError, RunSummary};
use std::time::Duration;
use thiserror::Error;
use tokio_util::sync::CancellationToken;

/// Tick period, ms: fine enough for step starts and deadlines.
pub const TICK_MS: u64 = 5;

/// Why the head process could not run.
#[derive(Debug, Error)]
pub enum ProcessError {
    #[error(transparent)]
    Config(#[from] ConfigError),
    #[error("transport: {0}")]
    Transport(#[from] runtime::transport::TransportError),
}

/// What the process did, returned at shutdown.
#[derive(Clone, Debug)]
pub struct Summary {
    pub counters: Counters,
    pub run: RunSummary,
}

/// Run a head on `transport` until `shutdown` is cancelled or the transport closes.
///
/// # Errors
/// The transport cannot open.
pub async fn run(
    head_cfg: HeadConfig,
    transport: runtime::transport::TransportConfig,
    clock: HostClock,
    shutdown: CancellationToken,
) -> Result<Summary, ProcessError> {
    let leader: Option<NodeId> = head_cfg.server;
    let mut head = HeadNode::new(head_cfg);
    let cfg = runtime::ProcessConfig::new(transport, leader, Duration::from_millis(TICK_MS));
    let run = match runtime::run(&mut head, cfg, clock, no_sensors(), &mut NoHooks, shutdown).await {
        Ok(run) => run,
        Err(RunError::Transport(e)) => return Err(e.into()),
        Err(RunError::Node(never)) => match never {},
    };
    let summary = Summary {
        counters: *head.counters(),
        run,
    };
    tracing::info!(
        steps = summary.counters.steps,
        applied = summary.counters.applied,
        late = summary.counters.late,
        send_failures = summary.run.send_failures,
        "head stopped"
    );
    Ok(summary)
}
