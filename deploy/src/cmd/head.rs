//! `ocelli head --id N [--scenario FILE] [--transport ipc|tcp]`: run one cluster head as its
//! own process until SIGINT/SIGTERM (a second signal aborts). Prints a JSON summary of what
//! it did on standard output when it stops.

use super::common::{TransportArg, load_scenario, stop_signal, transport_or_scenario};
use anyhow::{Context, Result};
use node_head::process::{ProcessConfig, run as run_head};
use serde_json::json;
use std::net::SocketAddr;
use std::path::PathBuf;
use std::process::ExitCode;
use tokio_util::sync::CancellationToken;

#[derive(clap::Args, Debug)]
pub struct Args {
    /// Scenario file (the embedded default when omitted).
    #[arg(long)]
    pub scenario: Option<PathBuf>,
    /// This head's node id in the scenario.
    #[arg(long)]
    pub id: u32,
    /// Transport (the scenario's `network.transport` when omitted).
    #[arg(long, value_enum)]
    pub transport: Option<TransportArg>,
    /// TCP: listen here instead of the scenario's address (port 0 picks one).
    #[arg(long)]
    pub listen: Option<SocketAddr>,
}

pub fn run(args: Args) -> Result<ExitCode> {
    let scenario = load_scenario(args.scenario.as_ref())?;
    let transport = transport_or_scenario(args.transport, &scenario);
    let cfg = ProcessConfig {
        scenario,
        id: args.id,
        transport,
        listen: args.listen,
    };
    // The transport's futures are not `Send`: one thread drives the head, others serve IO.
    let rt = tokio::runtime::Builder::new_multi_thread()
        .enable_all()
        .build()
        .context("cannot start the tokio runtime")?;
    let summary = rt.block_on(async {
        let token = CancellationToken::new();
        let stop = token.clone();
        tokio::spawn(async move {
            stop_signal().await;
            tracing::info!("stopping (a second signal aborts)");
            stop.cancel();
            stop_signal().await;
            eprintln!("second signal: aborting");
            std::process::exit(130);
        });
        run_head(cfg, token).await
    })?;
    let c = summary.counters;
    let out = json!({
        "head": args.id,
        "steps": c.steps,
        "applied": c.applied,
        "late": c.late,
        "duplicate": c.duplicate,
        "rejected": c.rejected,
        "births": c.births,
        "deaths": c.deaths,
        "left_world": c.left_world,
        "merges": c.merges,
        "handovers": c.handovers,
        "commands": c.commands,
        "numeric_failures": c.numeric_failures,
        "mean_active_cameras": c.mean_active_cameras(),
        "mean_rssi_nodes": c.mean_rssi_nodes(),
        "mean_power_mw": c.mean_power_mw(),
        "sent": summary.sent,
        "send_failures": summary.send_failures,
        "peers_down": summary.peers_down,
    });
    println!("{out}");
    Ok(ExitCode::SUCCESS)
}
