//! The `ocelli` command line: one binary, one subcommand per job. Each subcommand lives in its
//! own module under `cmd/`; this file only parses and dispatches (one line per subcommand in
//! [`Command`] and in [`dispatch`]), and groups `--help` by what users do ([`GROUPS`]).

use crate::cmd;
use clap::{CommandFactory, FromArgMatches, Parser, Subcommand};
use std::io::IsTerminal;
use std::process::ExitCode;

#[derive(Parser, Debug)]
#[command(
    name = "ocelli",
    version,
    about = "Track moving targets with a network of smart cameras",
    disable_help_subcommand = true,
    after_help = "Logs go to standard error: RUST_LOG sets what is logged (default `info`, e.g. \
                  RUST_LOG=debug or RUST_LOG=node_head=debug), --log-json makes them JSON \
                  lines; `launch` passes both to every node it starts. `ocelli COMMAND --help` \
                  says more."
)]
pub struct Cli {
    /// Log as JSON lines (for machines) instead of human text; passed to every child process.
    #[arg(long, global = true)]
    pub log_json: bool,
    #[command(subcommand)]
    pub command: Command,
}

#[derive(Subcommand, Debug)]
pub enum Command {
    /// Start every node of a scenario on this host, each its own supervised process.
    Launch(cmd::launch::Args),
    /// Render per-host configuration (scenario, systemd units, system user) for real machines.
    Deploy(cmd::deploy::Args),
    /// Run one camera node (until SIGINT, SIGTERM or SIGHUP).
    Camera(cmd::camera::Args),
    /// Run one cluster head (until SIGINT, SIGTERM or SIGHUP).
    Head(cmd::head::Args),
    /// Run the server: membership, handover, global ids, time leader, recording.
    Server(cmd::server::Args),
    /// Run a scenario's nodes in one process on a virtual clock (deterministic for a seed).
    Sim(cmd::sim::Args),
    /// Reproduce a paper's experiment in the simulation; our table beside the paper's.
    Experiment(cmd::experiment::Args),
    /// Re-run a logging run's recording through the heads with another method and policy.
    Replay(cmd::replay::Args),
    /// Fuse external detections (JSON Lines, any detector) into estimates.
    Fuse(cmd::fuse::Args),
    /// Measure parts of the system; prints JSON.
    #[command(subcommand)]
    Bench(Bench),
    /// Undistort CSV rows (OpenCV test-vector format) from stdin: one `x,y` line per row.
    Undistort(cmd::undistort::Args),
    /// Print the report of a recording (table or JSON).
    Report(cmd::report::Args),
    /// Export the tracks of a recording as CSV or JSON Lines.
    Export(cmd::export::Args),
    /// Print, check or survey scenarios.
    Scenario(cmd::scenario::Args),
    /// Print a shell completion script (bash, zsh, fish, elvish, powershell).
    Completions(cmd::shell::CompletionArgs),
    /// Write the man pages (`ocelli.1` on standard output, or every page into a folder).
    Man(cmd::shell::ManArgs),
    /// Run one acoustic node (`--id N`), or survey fingerprints / locate a sound (paper 001).
    Acoustic(cmd::acoustic::Args),
    /// Run the visualization node: a client of the server serving the live map, the 3D view,
    /// `/api/state`, `/metrics` and KML over HTTP.
    Viewer(cmd::viewer::Args),
    /// Play a server's recording back in the viewer's pages (play, pause, time slider).
    View(cmd::view::Args),
    /// Run one transport endpoint as a process (for tests and probes).
    #[command(hide = true)]
    Peer(cmd::peer::Args),
}

/// `--help`'s groups: what users do, and the subcommands for it. A subcommand named in no
/// group is listed under "More".
pub const GROUPS: &[(&str, &[&str])] = &[
    ("Run a cluster", &["launch", "deploy"]),
    (
        "Run one node",
        &["camera", "head", "server", "acoustic", "viewer"],
    ),
    (
        "Study",
        &["sim", "experiment", "replay", "fuse", "bench", "undistort"],
    ),
    ("Inspect recordings", &["report", "export", "view"]),
    ("Set up", &["scenario", "completions", "man"]),
];

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
    /// Fusing external detections: time against detections per time stamp.
    Fuse(cmd::bench::ScaleArgs),
    /// The grid estimator's update on 200×200 cells and the ILD of one audio frame.
    Grid(cmd::bench::ScaleArgs),
}

/// Run one parsed command.
fn dispatch(command: Command, log_json: bool) -> anyhow::Result<ExitCode> {
    match command {
        Command::Launch(args) => cmd::launch::run(args, log_json),
        Command::Deploy(args) => cmd::deploy::run(args),
        Command::Camera(args) => cmd::camera::run_cmd(args),
        Command::Head(args) => cmd::head::run(args),
        Command::Server(args) => cmd::server::run(args),
        Command::Sim(args) => cmd::sim::run(args),
        Command::Experiment(args) => cmd::experiment::run(args),
        Command::Replay(args) => cmd::replay::run(args),
        Command::Fuse(args) => cmd::fuse::run(args),
        Command::Bench(Bench::Head(args)) => cmd::bench::head(args),
        Command::Bench(Bench::Camera(args)) => cmd::bench::camera(args),
        Command::Bench(Bench::Server(args)) => cmd::bench::server(args),
        Command::Bench(Bench::Transport(args)) => cmd::bench::transport(args),
        Command::Bench(Bench::Fuse(args)) => cmd::bench::fuse(args),
        Command::Bench(Bench::Grid(args)) => cmd::bench::grid(args),
        Command::Acoustic(args) => cmd::acoustic::run_cmd(args),
        Command::Viewer(args) => cmd::viewer::run(args),
        Command::View(args) => cmd::view::run(args),
        Command::Undistort(args) => cmd::undistort::run(args),
        Command::Report(args) => cmd::report::run(args),
        Command::Export(args) => cmd::export::run(args),
        Command::Scenario(args) => cmd::scenario::run(args),
        Command::Completions(args) => cmd::shell::completions(&args),
        Command::Man(args) => cmd::shell::man(&args),
        Command::Peer(args) => cmd::peer::run(args),
    }
}

/// The subcommands under their [`GROUPS`] headings, as `--help` lists them.
fn grouped_subcommands(cmd: &clap::Command) -> String {
    use std::fmt::Write;
    let visible: Vec<&clap::Command> = cmd.get_subcommands().filter(|c| !c.is_hide_set()).collect();
    let width = visible.iter().map(|c| c.get_name().len()).max().unwrap_or(0);
    let line = |out: &mut String, c: &clap::Command| {
        let about = c.get_about().map(ToString::to_string).unwrap_or_default();
        let _ = writeln!(out, "  {:width$}  {about}", c.get_name());
    };
    let mut out = String::new();
    for (heading, names) in GROUPS {
        let _ = writeln!(out, "{heading}:");
        for name in *names {
            if let Some(c) = visible.iter().find(|c| c.get_name() == *name) {
                line(&mut out, c);
            }
        }
        out.push('\n');
    }
    let rest: Vec<_> = visible
        .iter()
        .filter(|c| GROUPS.iter().all(|(_, names)| !names.contains(&c.get_name())))
        .collect();
    if !rest.is_empty() {
        out.push_str("More:\n");
        for c in rest {
            line(&mut out, c);
        }
        out.push('\n');
    }
    out
}

/// The whole CLI definition, with `--help` grouped (what completions and man pages are made
/// from too).
pub fn command() -> clap::Command {
    let cmd = Cli::command();
    let groups = grouped_subcommands(&cmd);
    cmd.help_template(format!(
        "{{about-with-newline}}\n{{usage-heading}} {{usage}}\n\n{groups}Options:\n{{options}}{{after-help}}"
    ))
}

/// Install the tracing subscriber (`RUST_LOG`, default `info`) on standard error: colour only
/// on a terminal (and not with `NO_COLOR`), so log files hold plain text.
fn init_tracing(json: bool) {
    use tracing_subscriber::EnvFilter;
    let filter = EnvFilter::try_from_default_env().unwrap_or_else(|_| EnvFilter::new("info"));
    let colour = std::io::stderr().is_terminal() && std::env::var_os("NO_COLOR").is_none();
    let builder = tracing_subscriber::fmt()
        .with_env_filter(filter)
        .with_ansi(colour)
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
            | Command::Fuse(_)
            | Command::Deploy(_)
            | Command::Experiment(_)
            | Command::Completions(_)
            | Command::Man(_)
    )
}

fn default_sigpipe() {
    #[allow(unsafe_code)]
    // SAFETY: restoring the default disposition of SIGPIPE before any thread starts.
    unsafe {
        libc::signal(libc::SIGPIPE, libc::SIG_DFL);
    }
}

/// Files the product writes are not world-readable: new files 0640, new folders 0750.
fn private_files() {
    #[allow(unsafe_code)]
    // SAFETY: umask(2) has no memory-safety preconditions.
    unsafe {
        libc::umask(0o027);
    }
}

/// An error and its causes, each said once: a cause whose text the message already holds
/// (`cannot read x: No such file…` over `No such file…`) is not repeated.
pub fn error_text(e: &anyhow::Error) -> String {
    let mut text = String::new();
    for cause in e.chain() {
        let s = cause.to_string();
        if !text.contains(&s) {
            if !text.is_empty() {
                text.push_str(": ");
            }
            text.push_str(&s);
        }
    }
    text
}

pub fn main() -> ExitCode {
    let matches = command().get_matches();
    let cli = match Cli::from_arg_matches(&matches) {
        Ok(cli) => cli,
        Err(e) => e.exit(),
    };
    if filter_command(&cli.command) {
        default_sigpipe();
    }
    private_files();
    init_tracing(cli.log_json);
    match dispatch(cli.command, cli.log_json) {
        Ok(code) => code,
        Err(e) => {
            eprintln!("error: {}", error_text(&e));
            ExitCode::FAILURE
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_cli_definition_is_consistent_and_every_command_has_a_group() {
        command().debug_assert();
        let cmd = command();
        for c in cmd.get_subcommands().filter(|c| !c.is_hide_set()) {
            assert!(
                GROUPS.iter().any(|(_, names)| names.contains(&c.get_name())),
                "`{}` is in no --help group",
                c.get_name()
            );
        }
    }

    #[test]
    fn an_error_names_each_cause_once() {
        let io = std::io::Error::new(
            std::io::ErrorKind::NotFound,
            "No such file or directory (os error 2)",
        );
        let e = anyhow::Error::new(io).context("cannot read x.toml: No such file or directory (os error 2)");
        assert_eq!(
            error_text(&e),
            "cannot read x.toml: No such file or directory (os error 2)"
        );
        let e = anyhow::anyhow!("inner").context("outer");
        assert_eq!(error_text(&e), "outer: inner");
    }
}
