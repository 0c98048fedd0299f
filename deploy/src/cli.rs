//! The `ocelli` command line: one binary, one subcommand per job. Each subcommand lives in its
//! own module under `cmd/`; this file only parses and dispatches.

use crate::cmd;
use clap::{Parser, Subcommand};
use std::process::ExitCode;

#[derive(Parser, Debug)]
#[command(
    name = "ocelli",
    version,
    about = "Track moving targets with a network of smart cameras"
)]
pub struct Cli {
    /// Log as JSON lines (for machines) instead of human text.
    #[arg(long, global = true)]
    pub log_json: bool,
    #[command(subcommand)]
    pub command: Command,
}

#[derive(Subcommand, Debug)]
pub enum Command {
    /// Print or check scenarios.
    Scenario(cmd::scenario::Args),
    /// Run the server: membership, handover, global ids, time leader, recording.
    Server(cmd::server::Args),
    /// Run one camera node (until SIGINT/SIGTERM).
    Camera(cmd::camera::Args),
    /// Undistort CSV rows (OpenCV test-vector format) from stdin: one `x,y` line per row.
    Undistort(cmd::undistort::Args),
    /// Print the report of a server recording (table or JSON).
    Report(cmd::report::Args),
    /// Export the tracks of a server recording as CSV or JSON Lines.
    Export(cmd::export::Args),
    /// Start every node of a scenario on this host, each its own process (default scenario
    /// when none is given).
    Launch(cmd::launch::Args),
    /// Render per-host configuration (scenario, systemd units, system user) for real machines.
    Deploy(cmd::deploy::Args),
    /// Run a scenario's nodes in one process on a virtual clock (deterministic for a seed).
    Sim(cmd::sim::Args),
    /// Run one cluster head as its own process.
    Head(cmd::head::Args),
    /// Fuse external detections (JSON Lines) with a method; estimates as JSON Lines.
    Replay(cmd::replay::Args),
    /// Reproduce a paper's experiment in the simulation; our table beside the paper's.
    Experiment(cmd::experiment::Args),
    /// Measure parts of the system; prints JSON.
    #[command(subcommand)]
    Bench(Bench),
    /// Run one acoustic node (`--id N`), or survey fingerprints / locate a sound (paper 001).
    Acoustic(cmd::acoustic::Args),
    /// Run one transport endpoint as a process (for tests and probes).
    #[command(hide = true)]
    Peer(cmd::peer::Args),
}

/// What `ocelli bench` measures.
#[derive(Subcommand, Debug)]
pub enum Bench {
    /// The head's EIF update and activation decision.
    Head(cmd::bench::ScaleArgs),
    /// Camera node: segmentation + undistortion + contribution per frame.
    Camera(cmd::bench::CameraArgs),
    /// Server core (track reports, ticks), recording appends and restore.
    Server(cmd::bench::ScaleArgs),
    /// One-way latency over iceoryx2 and TCP, encode/decode cost per message kind.
    Transport(cmd::bench::TransportArgs),
    /// The grid estimator's update on 200×200 cells and the ILD of one audio frame.
    Grid(cmd::bench::ScaleArgs),
}

/// Install the tracing subscriber (`RUST_LOG`, default `info`) on standard error.
fn init_tracing(json: bool) {
    use tracing_subscriber::EnvFilter;
    let filter = EnvFilter::try_from_default_env().unwrap_or_else(|_| EnvFilter::new("info"));
    let builder = tracing_subscriber::fmt()
        .with_env_filter(filter)
        .with_writer(std::io::stderr);
    let _ = if json {
        builder.json().try_init()
    } else {
        builder.try_init()
    };
}

/// Commands that print results to standard output end quietly when the reader goes away
/// (`ocelli sim | head`), as Unix filters do. Rust ignores SIGPIPE, which turns a closed pipe
/// into a panic in `println!`; node processes keep ignoring it, since a peer closing a socket
/// must not kill them.
fn filter_command(c: &Command) -> bool {
    matches!(
        c,
        Command::Scenario(_)
            | Command::Undistort(_)
            | Command::Report(_)
            | Command::Export(_)
            | Command::Sim(_)
            | Command::Replay(_)
            | Command::Deploy(_)
            | Command::Experiment(_)
    )
}

fn default_sigpipe() {
    #[allow(unsafe_code)]
    // SAFETY: restoring the default disposition of SIGPIPE before any thread starts.
    unsafe {
        libc::signal(libc::SIGPIPE, libc::SIG_DFL);
    }
}

pub fn main() -> ExitCode {
    let cli = Cli::parse();
    if filter_command(&cli.command) {
        default_sigpipe();
    }
    init_tracing(cli.log_json);
    let result = match cli.command {
        Command::Scenario(args) => cmd::scenario::run(args),
        Command::Server(args) => cmd::server::run(args),
        Command::Camera(args) => cmd::camera::run_cmd(args),
        Command::Undistort(args) => cmd::undistort::run(args),
        Command::Report(args) => cmd::report::run(args),
        Command::Export(args) => cmd::export::run(args),
        Command::Sim(args) => cmd::sim::run(args),
        Command::Deploy(args) => cmd::deploy::run(args),
        Command::Launch(args) => cmd::launch::run(args),
        Command::Head(args) => cmd::head::run(args),
        Command::Replay(args) => cmd::replay::run(args),
        Command::Experiment(args) => cmd::experiment::run(args),
        Command::Bench(Bench::Head(args)) => cmd::bench::head(args),
        Command::Bench(Bench::Camera(args)) => cmd::bench::camera(args),
        Command::Bench(Bench::Server(args)) => cmd::bench::server(args),
        Command::Bench(Bench::Transport(args)) => cmd::bench::transport(args),
        Command::Bench(Bench::Grid(args)) => cmd::bench::grid(args),
        Command::Acoustic(args) => cmd::acoustic::run_cmd(args),
        Command::Peer(args) => cmd::peer::run(args),
    };
    match result {
        Ok(code) => code,
        Err(e) => {
            eprintln!("error: {e:#}");
            ExitCode::FAILURE
        }
    }
}
