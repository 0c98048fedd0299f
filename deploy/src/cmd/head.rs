//! `ocelli head --id N [--scenario FILE] [--transport ipc|tcp]`: run one cluster head as its
//! own process until SIGINT/SIGTERM (a second signal aborts). Prints a JSON summary of what
//! it did on standard output when it stops.

use super::common::{
    ExitSummaryArg, ScenarioArg, SecurityArgs, TransportArg, node_of_role, run_node, transport_or_scenario,
};
use anyhow::Result;
use node_head::HeadConfig;
use node_head::process::run as run_head;
use proto::NodeId;
use runtime::HostClock;
use runtime::config::transport_config;
use serde_json::json;
use std::net::SocketAddr;
use std::process::ExitCode;

#[derive(clap::Args, Debug)]
pub struct Args {
    #[command(flatten)]
    pub scenario: ScenarioArg,
    /// This head's node id in the scenario.
    #[arg(long)]
    pub id: u32,
    /// Transport (the scenario's `network.transport` when omitted).
    #[arg(long, value_enum)]
    pub transport: Option<TransportArg>,
    #[command(flatten)]
    pub security: SecurityArgs,
    #[command(flatten)]
    pub exit: ExitSummaryArg,
    /// TCP: listen here instead of the scenario's address (port 0 picks one).
    #[arg(long)]
    pub listen: Option<SocketAddr>,
}

pub fn run(args: Args) -> Result<ExitCode> {
    let scenario = args.scenario.load()?;
    node_of_role(&scenario, args.id, proto::scenario::NodeRole::Head)?;
    let kind = transport_or_scenario(args.transport, &scenario);
    let head_cfg = HeadConfig::from_scenario(&scenario, args.id)?;
    let clock = HostClock::follower();
    let transport = transport_config(
        &scenario,
        NodeId(args.id),
        kind,
        &clock,
        args.listen,
        &args.security.link_security(),
    )?;
    let summary =
        run_node(|shutdown| async move { Ok(run_head(head_cfg, transport, clock, shutdown).await?) })?;
    args.exit.write(&summary.run);
    let c = summary.counters;
    let out = json!({
        "head": args.id,
        "steps": c.steps,
        "applied": c.applied,
        "late": c.late,
        "duplicate": c.duplicate,
        "rejected": c.rejected,
        "births": c.births,
        "births_elsewhere": c.births_elsewhere,
        "deaths": c.deaths,
        "left_world": c.left_world,
        "merges": c.merges,
        "handovers": c.handovers,
        "commands": c.commands,
        "numeric_failures": c.numeric_failures,
        "mean_active_cameras": c.mean_active_cameras(),
        "mean_rssi_nodes": c.mean_rssi_nodes(),
        "mean_tentative_tracks": c.mean_tentative(),
        "mean_coasting_tracks": c.mean_coasting(),
        "mean_power_mw": c.mean_power_mw(),
        "sent": summary.run.sent,
        "send_failures": summary.run.send_failures,
        "peers_down": summary.run.peers_down,
    });
    println!("{out}");
    Ok(ExitCode::SUCCESS)
}
