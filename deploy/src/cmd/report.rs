//! `ocelli report`: the run report of a recording (error against ground truth when the
//! scenario has targets, sensors per step, energy, messages, sync), as a table or JSON.

use anyhow::{Context, Result};
use node_server::analysis::load;
use node_server::report::compute;
use proto::ClusterTime;
use proto::scenario::Scenario;
use std::path::PathBuf;
use std::process::ExitCode;

#[derive(clap::Args, Debug)]
pub struct Args {
    /// The server's recording file.
    pub recording: PathBuf,
    /// Scenario with the ground truth (default: the one stored in the recording).
    #[arg(long)]
    pub scenario: Option<PathBuf>,
    /// Print JSON instead of the table.
    #[arg(long)]
    pub json: bool,
    /// Also write the JSON report to this file.
    #[arg(long)]
    pub write: Option<PathBuf>,
    /// Cluster time (ns) at which the scenario's trajectories start.
    #[arg(long, default_value_t = 0)]
    pub t0_ns: i64,
}

pub fn run(args: Args) -> Result<ExitCode> {
    let scenario = args.scenario.as_deref().map(Scenario::load).transpose()?;
    let loaded = load(&args.recording, scenario)?;
    // Scored against the scenario's simulated targets when it has any, as they were at
    // `--t0-ns` on the recording's clock.
    let truth = sim::WorldTruth::of(&loaded.scenario, ClusterTime(args.t0_ns))?;
    let report = compute(
        &loaded,
        truth.as_ref().map(|t| t as &dyn node_server::report::Truth),
    );
    let json = serde_json::to_string_pretty(&report)?;
    if let Some(p) = &args.write {
        std::fs::write(p, &json).with_context(|| format!("writing {}", p.display()))?;
    }
    if args.json {
        println!("{json}");
    } else {
        print!("{}", report.to_table());
    }
    Ok(ExitCode::SUCCESS)
}
