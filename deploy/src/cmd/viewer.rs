//! `ocelli viewer`: the visualization node as its own process — a client of the scenario's
//! server over its transport, serving the live map, the 3D view, `/api/state`, `/metrics` and
//! KML on `--listen` (see `view`).

use super::common::{ExitSummaryArg, ScenarioArg, TransportArg, run_node, transport_or_scenario};
use anyhow::{Context, Result};
use proto::NodeId;
use runtime::HostClock;
use runtime::config::client_transport_config;
use std::net::SocketAddr;
use std::process::ExitCode;
use view::node::ViewerConfig;

/// Where the viewer serves unless told otherwise.
pub const DEFAULT_LISTEN: &str = "127.0.0.1:8080";

#[derive(clap::Args, Debug)]
pub struct Args {
    #[command(flatten)]
    pub scenario: ScenarioArg,
    /// This viewer's node id: one the scenario does not use (default: the first free from 900).
    #[arg(long)]
    pub id: Option<u32>,
    /// Transport (default: the scenario's `network.transport`).
    #[arg(long, value_enum)]
    pub transport: Option<TransportArg>,
    /// Serve HTTP here.
    #[arg(long, default_value = DEFAULT_LISTEN)]
    pub listen: SocketAddr,
    /// Update period asked of the server, ms (default: the filter's step).
    #[arg(long, default_value_t = 0)]
    pub period_ms: u32,
    #[command(flatten)]
    pub security: super::common::SecurityArgs,
    #[command(flatten)]
    pub exit: ExitSummaryArg,
}

pub fn run(args: Args) -> Result<ExitCode> {
    let scenario = args.scenario.load()?;
    let id = NodeId(args.id.unwrap_or_else(|| view::node::free_id(&scenario).0));
    let kind = transport_or_scenario(args.transport, &scenario);
    let transport = client_transport_config(
        &scenario,
        id,
        proto::Role::Viewer,
        kind,
        &HostClock::follower(),
        &args.security.link_security(),
    )?;
    let mut cfg = ViewerConfig::for_scenario(&scenario, id)?;
    cfg.period_ms = args.period_ms;
    let initial = view::ViewState::with_scenario(&scenario);
    let listen = args.listen;
    let summary = run_node(|shutdown| async move {
        let listener = tokio::net::TcpListener::bind(listen)
            .await
            .with_context(|| format!("the viewer cannot listen on {listen}"))?;
        let url = format!("http://{}", listener.local_addr()?);
        // A log line, not a bare print: under `--log-json` every line of the log is JSON
        // (`ocelli launch` prints the URL itself).
        tracing::info!(%url, node = %id, "viewer serving");
        Ok(view::live::run(cfg, initial, transport, listener, shutdown).await?)
    })?;
    args.exit.write(&summary);
    Ok(ExitCode::SUCCESS)
}
