//! `ocelli launch [SCENARIO]`: the one-command local cluster (see `crate::launch`).

use super::common::{TransportArg, load_scenario};
use crate::launch::{LaunchOptions, launch};
use anyhow::Result;
use std::net::SocketAddr;
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
    /// Serve the viewer (live map, 3D view, metrics, KML) here; a busy default port is
    /// replaced by a free one.
    #[arg(long, default_value = super::viewer::DEFAULT_LISTEN, conflicts_with = "no_view")]
    pub view: SocketAddr,
    /// Start no viewer.
    #[arg(long)]
    pub no_view: bool,
}

pub fn run(args: Args) -> Result<ExitCode> {
    let scenario = load_scenario(args.scenario.as_ref())?;
    let opts = LaunchOptions {
        transport: args.transport.kind(),
        duration: args.duration.map(Duration::from_secs_f64),
        run_dir: args.run_dir,
        record: args.record,
        progress: !args.quiet,
        record_measurements: args.record_measurements,
        view: (!args.no_view).then(|| view_address(args.view)),
    };
    let report = launch(scenario, &opts)?;
    if args.json {
        println!("{}", serde_json::to_string_pretty(&report)?);
    } else {
        print!("{}", report.to_table());
    }
    Ok(ExitCode::SUCCESS)
}

/// `addr` if it can be bound now; port 0, or the default port when it is taken (another
/// launch, another viewer), becomes a free port on the same interface, said on standard error.
fn view_address(addr: SocketAddr) -> SocketAddr {
    let is_default = addr.to_string() == super::viewer::DEFAULT_LISTEN;
    if addr.port() != 0 && (!is_default || std::net::TcpListener::bind(addr).is_ok()) {
        return addr;
    }
    match std::net::TcpListener::bind(SocketAddr::new(addr.ip(), 0)).and_then(|l| l.local_addr()) {
        Ok(free) => {
            if is_default {
                eprintln!("{addr} is busy: the viewer serves on {free} instead");
            }
            free
        }
        Err(_) => addr,
    }
}
