//! `ocelli launch`: the one-command local cluster (see `crate::launch`).

use super::common::{ScenarioArg, TransportArg, seconds};
use crate::launch::chaos::ChaosOptions;
use crate::launch::{LaunchOptions, launch};
use crate::supervisor::RestartPolicy;
use anyhow::Result;
use std::io::IsTerminal;
use std::net::SocketAddr;
use std::path::PathBuf;
use std::process::ExitCode;
use std::time::Duration;

#[derive(clap::Args, Debug)]
pub struct Args {
    #[command(flatten)]
    pub scenario: ScenarioArg,
    /// `ipc` (iceoryx2 shared memory) or `tcp` (loopback sockets).
    #[arg(long, value_enum, default_value = "ipc")]
    pub transport: TransportArg,
    /// Stop after this many seconds (default: run until SIGINT, SIGTERM or SIGHUP).
    #[arg(long, value_parser = seconds)]
    pub duration: Option<f64>,
    /// Print only the final report, as JSON, on standard output.
    #[arg(long)]
    pub json: bool,
    /// The run's folder: effective scenario, node list, logs and (by default) the recording.
    /// Default: a new time-stamped folder under `ocelli-runs/`. It must be empty or absent.
    #[arg(long, value_name = "DIR")]
    pub run_dir: Option<PathBuf>,
    /// Where the server's recording goes (default: `recording.ocrec` in the run's folder). It
    /// must not exist.
    #[arg(long, value_name = "FILE")]
    pub record: Option<PathBuf>,
    /// Write over a run folder that holds files and replace an existing recording.
    #[arg(long)]
    pub force: bool,
    /// No live progress lines (they are shown only when standard error is a terminal).
    #[arg(long)]
    pub quiet: bool,
    /// Leave a node that crashed down instead of restarting it with backoff.
    #[arg(long)]
    pub no_restart: bool,
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
    /// Over TCP, plain links without TLS (the scenario's `[network] insecure = true`): anyone
    /// reaching a port can pose as any node. Without it a launch makes certificates for the run.
    #[arg(long)]
    pub insecure: bool,
    /// Chaos mode, for resilience tests: every SECONDS on average (each gap half to one and a
    /// half of it) SIGKILL a random node — the server, a head, a camera — and let the
    /// supervisor restart it (these kills never count towards giving up on a node). Each kill
    /// is a line of `chaos.jsonl` in the run's folder. No kill in the last 10 s of a
    /// `--duration`.
    #[arg(long, value_parser = seconds, value_name = "SECONDS", conflicts_with = "no_restart")]
    pub chaos_every: Option<f64>,
    /// The chaos mode's seed (victims and times).
    #[arg(long, default_value_t = 1, requires = "chaos_every")]
    pub chaos_seed: u64,
    /// No chaos kill before this many seconds into the run.
    #[arg(long, value_parser = seconds, default_value_t = 10.0, requires = "chaos_every")]
    pub chaos_after: f64,
    /// Start every node but these (ids, comma-separated or repeated): they run on other hosts,
    /// or are left out to see how the rest copes. A head left out is declared down 10 s after
    /// the first node joins, and its cameras go to the live heads. Never the server.
    #[arg(long, value_name = "ID", value_delimiter = ',')]
    pub skip: Vec<u32>,
}

pub fn run(args: Args, log_json: bool) -> Result<ExitCode> {
    let mut scenario = args.scenario.load()?;
    if args.insecure {
        scenario.network.insecure = true;
    }
    let opts = LaunchOptions {
        transport: args.transport.kind(),
        duration: args.duration.map(Duration::from_secs_f64),
        run_dir: args.run_dir,
        record: args.record,
        force: args.force,
        progress: !args.quiet && std::io::stderr().is_terminal(),
        record_measurements: args.record_measurements,
        log_json,
        restart: (!args.no_restart).then(RestartPolicy::default),
        view: (!args.no_view).then(|| view_address(args.view)),
        chaos: args.chaos_every.map(|every| ChaosOptions {
            every: Duration::from_secs_f64(every),
            seed: args.chaos_seed,
            after: Duration::from_secs_f64(args.chaos_after),
        }),
        skip: args.skip,
    };
    let launched = launch(scenario, &opts)?;
    for (node, n) in &launched.restarts {
        tracing::warn!(node = %node, restarts = n, "node was restarted during the run");
    }
    let report = &launched.report.report;
    if args.json {
        let mut json = crate::launch::latency::report_json(report, &launched.report.loaded)?;
        if let Some(map) = json.as_object_mut() {
            map.insert("undelivered".into(), serde_json::to_value(&launched.undelivered)?);
        }
        println!("{}", serde_json::to_string_pretty(&json)?);
    } else {
        print!("{}", report.to_table());
        if let Some(age) = crate::launch::latency::of(&launched.report.loaded) {
            print!("{}", crate::launch::latency::to_line(&age));
        }
        print!("{}", launched.undelivered.to_line());
        print!(
            "{}",
            crate::launch::usage::to_table(&launched.usage, launched.wall_s)
        );
    }
    for r in &launched.usage {
        tracing::info!(
            role = %r.role,
            processes = r.processes,
            cores = r.cores,
            rss_mib_total = r.rss_mib_total,
            "CPU and memory"
        );
    }
    tracing::info!(
        run = %launched.run.dir.display(),
        recording = %launched.run.recording.display(),
        "run finished; `ocelli report RECORDING` prints this report again"
    );
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
