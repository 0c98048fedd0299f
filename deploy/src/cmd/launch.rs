//! `ocelli launch [SCENARIO]`: the one-command local cluster (see `crate::launch`).

use super::common::{TransportArg, load_scenario};
use crate::launch::{LaunchOptions, launch};
use anyhow::Result;
use std::path::PathBuf;
use std::process::ExitCode;
use std::time::Duration;

#[derive(clap::Args, Debug)]
pub struct Args {
    /// Scenario file (the embedded default when omitted).
    pub scenario: Option<PathBuf>,
    /// `ipc` (iceoryx2 shared memory) or `tcp` (loopback sockets).
    #[arg(long, value_enum, default_value = "ipc")]
    pub transport: TransportArg,
    /// Stop after this many seconds (default: run until Ctrl-C).
    #[arg(long)]
    pub duration: Option<f64>,
    /// Print the final report as JSON on standard output.
    #[arg(long)]
    pub json: bool,
    /// Where the server's recording goes.
    #[arg(long, default_value = "ocelli-recording.ocrec")]
    pub record: PathBuf,
    /// Directory for the effective scenario and each node's log.
    #[arg(long, default_value = "ocelli-run")]
    pub run_dir: PathBuf,
    /// No live progress lines.
    #[arg(long)]
    pub quiet: bool,
    /// A logging run: every camera measures every frame whatever its mode and the server
    /// records it, so `ocelli replay` can re-run the recording with any method and policy.
    #[arg(long)]
    pub record_measurements: bool,
    /// Over TCP, plain links without TLS (the scenario's `[network] insecure = true`): anyone
    /// reaching a port can pose as any node. Without it a launch makes certificates for the run.
    #[arg(long)]
    pub insecure: bool,
}

pub fn run(args: Args) -> Result<ExitCode> {
    let mut scenario = load_scenario(args.scenario.as_ref())?;
    if args.insecure {
        scenario.network.insecure = true;
    }
    let opts = LaunchOptions {
        transport: args.transport.kind(),
        duration: args.duration.map(Duration::from_secs_f64),
        run_dir: args.run_dir,
        record: args.record,
        progress: !args.quiet,
        record_measurements: args.record_measurements,
    };
    let report = launch(scenario, &opts)?;
    if args.json {
        println!("{}", serde_json::to_string_pretty(&report)?);
    } else {
        print!("{}", report.to_table());
    }
    Ok(ExitCode::SUCCESS)
}
