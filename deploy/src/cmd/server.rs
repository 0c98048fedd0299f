//! `ocelli server`: run the server process (membership, handover, global ids, time leader,
//! recording) from a scenario, over iceoryx2 or TCP. Restarting it on the same recording resumes.

use super::common::{TransportArg, load_scenario, run_node, transport_or_scenario};
use anyhow::{Context, Result};
use node_server::process::{ProcessConfig, run as run_server};
use proto::NodeId;
use runtime::HostClock;
use runtime::config::transport_config;
use std::path::PathBuf;
use std::process::ExitCode;
use std::time::Duration;

#[derive(clap::Args, Debug)]
pub struct Args {
    /// Scenario file (default: the embedded default scenario).
    #[arg(long)]
    pub scenario: Option<PathBuf>,
    /// This server's node id (default: the scenario's server).
    #[arg(long)]
    pub id: Option<u32>,
    /// Transport (default: the scenario's `network.transport`).
    #[arg(long, value_enum)]
    pub transport: Option<TransportArg>,
    /// Recording file; resumed if it exists.
    #[arg(long)]
    pub record: PathBuf,
    /// Tick period, ms.
    #[arg(long, default_value_t = 50)]
    pub tick_ms: u64,
}

pub fn run(args: Args) -> Result<ExitCode> {
    let scenario = load_scenario(args.scenario.as_ref())?;
    let id = match args.id {
        Some(i) => i,
        None => {
            scenario
                .server()
                .context("the scenario declares no server; pass --id")?
                .id
        }
    };
    let kind = transport_or_scenario(args.transport, &scenario);
    // The leader's clock stamps the transport's own frames.
    let transport = transport_config(&scenario, NodeId(id), kind, &HostClock::leader(), None)?;
    let cfg = ProcessConfig {
        scenario,
        id: NodeId(id),
        transport,
        record: args.record,
        tick: Duration::from_millis(args.tick_ms.max(1)),
        sync_every: Duration::from_millis(500),
    };
    let summary = run_node(|shutdown| async move { Ok(run_server(cfg, shutdown).await?) })?;
    tracing::info!(
        records = summary.records,
        received = summary.run.received,
        sent = summary.run.sent,
        "server exited"
    );
    Ok(ExitCode::SUCCESS)
}
