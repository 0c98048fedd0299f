//! `ocelli server`: run the server process (membership, handover, global ids, time leader,
//! recording) from a scenario, over iceoryx2 or TCP. Restarting it on the same recording resumes.

use super::common::{
    ExitSummaryArg, ScenarioArg, SecurityArgs, TransportArg, node_of_role, run_node, transport_or_scenario,
};
use anyhow::{Context, Result};
use node_server::Origin;
use node_server::process::{ProcessConfig, run as run_server};
use proto::scenario::NodeRole;
use proto::{ClusterTime, NodeId};
use runtime::HostClock;
use runtime::config::transport_config;
use std::path::PathBuf;
use std::process::ExitCode;
use std::time::Duration;

#[derive(clap::Args, Debug)]
pub struct Args {
    #[command(flatten)]
    pub scenario: ScenarioArg,
    /// This server's node id (default: the scenario's server).
    #[arg(long)]
    pub id: Option<u32>,
    /// Transport (default: the scenario's `network.transport`).
    #[arg(long, value_enum)]
    pub transport: Option<TransportArg>,
    #[command(flatten)]
    pub security: SecurityArgs,
    #[command(flatten)]
    pub exit: ExitSummaryArg,
    /// Recording file; resumed if it exists.
    #[arg(long, value_name = "FILE")]
    pub record: PathBuf,
    /// Tick period, ms.
    #[arg(long, default_value_t = 50, value_parser = clap::value_parser!(u64).range(1..=10_000))]
    pub tick_ms: u64,
    /// Cluster time (ns since the Unix epoch) of scenario time 0, stored in a new recording
    /// (`ocelli launch` gives its cameras' epoch).
    #[arg(long, value_name = "NS")]
    pub epoch_ns: Option<i64>,
    /// The cameras sense the simulated world (`ocelli launch`): the recording says so, and its
    /// report is scored against the scenario's targets. Needs `--epoch-ns`.
    #[arg(long, requires = "epoch_ns")]
    pub simulated: bool,
}

pub fn run(args: Args) -> Result<ExitCode> {
    let scenario = args.scenario.load()?;
    let id = match args.id {
        Some(i) => i,
        None => {
            scenario
                .server()
                .with_context(|| format!("scenario {} declares no server; pass --id", scenario.name))?
                .id
        }
    };
    node_of_role(&scenario, id, NodeRole::Server)?;
    let kind = transport_or_scenario(args.transport, &scenario);
    // The leader's clock stamps the transport's own frames.
    let transport = transport_config(
        &scenario,
        NodeId(id),
        kind,
        &HostClock::leader(),
        None,
        &args.security.link_security(),
    )?;
    let cfg = ProcessConfig {
        scenario,
        id: NodeId(id),
        transport,
        record: args.record,
        tick: Duration::from_millis(args.tick_ms),
        sync_every: Duration::from_millis(500),
        origin: args.epoch_ns.map(|ns| Origin {
            t0: ClusterTime(ns),
            simulated: args.simulated,
        }),
    };
    let summary = run_node(|shutdown| async move { Ok(run_server(cfg, shutdown).await?) })?;
    args.exit.write(&summary.run);
    tracing::info!(
        records = summary.records,
        received = summary.run.received,
        sent = summary.run.sent,
        "server exited"
    );
    Ok(ExitCode::SUCCESS)
}
