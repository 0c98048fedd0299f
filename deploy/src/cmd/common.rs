//! What the subcommands share: the scenario flag, the transport flag, range-checked numbers,
//! the simulated network's flags, the stop signal and the warnings about damaged recordings.

use anyhow::Result;
use proto::scenario::{Scenario, TransportKind};
use std::path::PathBuf;

/// `--transport ipc|tcp`.
#[derive(clap::ValueEnum, Clone, Copy, Debug, PartialEq, Eq)]
pub enum TransportArg {
    /// iceoryx2 shared memory (same host).
    Ipc,
    /// TCP sockets (between hosts).
    Tcp,
}

impl TransportArg {
    pub fn kind(self) -> TransportKind {
        match self {
            TransportArg::Ipc => TransportKind::Ipc,
            TransportArg::Tcp => TransportKind::Tcp,
        }
    }
}

/// `--scenario FILE`: the same flag on every command that takes a scenario.
#[derive(clap::Args, Debug, Clone, Default)]
pub struct ScenarioArg {
    /// Scenario file (the embedded default scenario when omitted).
    #[arg(long, short = 's', value_name = "FILE")]
    pub scenario: Option<PathBuf>,
}

impl ScenarioArg {
    /// The file's scenario, or the embedded default.
    ///
    /// # Errors
    /// As [`load_scenario`].
    pub fn load(&self) -> Result<Scenario> {
        load_scenario(self.scenario.as_ref())
    }

    /// The file's scenario if one was given (commands where the default comes from elsewhere,
    /// e.g. a recording).
    ///
    /// # Errors
    /// As [`load_scenario`].
    pub fn load_given(&self) -> Result<Option<Scenario>> {
        Ok(self.scenario.as_deref().map(Scenario::load).transpose()?)
    }
}

/// The longest duration a command accepts, seconds (about 115 days).
pub const MAX_SECONDS: f64 = 1e7;

fn number(s: &str) -> Result<f64, String> {
    let x: f64 = s.trim().parse().map_err(|_| format!("`{s}` is not a number"))?;
    if x.is_finite() {
        Ok(x)
    } else {
        Err(format!("`{s}` is not a finite number"))
    }
}

/// A duration in seconds: finite, positive, at most [`MAX_SECONDS`].
///
/// # Errors
/// Anything else, saying what was expected.
pub fn seconds(s: &str) -> Result<f64, String> {
    let x = number(s)?;
    if x > 0.0 && x <= MAX_SECONDS {
        Ok(x)
    } else {
        Err(format!("expected seconds in (0, {MAX_SECONDS:e}], got {x}"))
    }
}

/// A probability in [0, 1].
///
/// # Errors
/// Anything else.
pub fn probability(s: &str) -> Result<f64, String> {
    let x = number(s)?;
    if (0.0..=1.0).contains(&x) {
        Ok(x)
    } else {
        Err(format!("expected a probability in [0, 1], got {x}"))
    }
}

/// A finite number ≥ 0.
///
/// # Errors
/// Anything else.
pub fn non_negative(s: &str) -> Result<f64, String> {
    let x = number(s)?;
    if x >= 0.0 {
        Ok(x)
    } else {
        Err(format!("expected a number ≥ 0, got {x}"))
    }
}

/// A finite number > 0.
///
/// # Errors
/// Anything else.
pub fn positive(s: &str) -> Result<f64, String> {
    let x = number(s)?;
    if x > 0.0 {
        Ok(x)
    } else {
        Err(format!("expected a number > 0, got {x}"))
    }
}

/// Any finite number.
///
/// # Errors
/// NaN, infinities and what is not a number.
pub fn finite(s: &str) -> Result<f64, String> {
    number(s)
}

/// How a node's TCP links are secured: `--tls-dir DIR` (the cluster's certificates, as
/// `ocelli deploy` writes them) or `--insecure` (plain TCP, loudly logged).
#[derive(clap::Args, Debug, Clone, Default)]
pub struct SecurityArgs {
    /// Directory with `ca.pem`, `node-<ID>.pem` and `node-<ID>.key` for mutual TLS over TCP.
    #[arg(long)]
    pub tls_dir: Option<PathBuf>,
    /// Plain TCP without TLS: anyone reaching a port can pose as any node. Closed test
    /// networks only (the scenario's `[network] insecure = true` says the same).
    #[arg(long)]
    pub insecure: bool,
}

impl SecurityArgs {
    pub fn link_security(&self) -> runtime::config::LinkSecurity {
        runtime::config::LinkSecurity {
            tls_dir: self.tls_dir.clone(),
            insecure: self.insecure,
        }
    }
}

/// `--exit-summary FILE`: where a node process appends its links' account when it stops.
#[derive(clap::Args, Debug, Clone, Default)]
pub struct ExitSummaryArg {
    /// When the node stops, append what its links delivered and what not (by kind, recipient
    /// and time) to FILE as one JSON line. `ocelli launch` gives each node its own file in the
    /// run folder, and its report tells what the cluster's stop left undelivered from what the
    /// run lost.
    #[arg(long, value_name = "FILE")]
    pub exit_summary: Option<PathBuf>,
}

impl ExitSummaryArg {
    /// Append `run` to the file, if one was given. A file that cannot be written is logged, not
    /// fatal: the node's work is done by now.
    pub fn write(&self, run: &runtime::RunSummary) {
        let Some(path) = &self.exit_summary else {
            return;
        };
        let written = serde_json::to_string(run)
            .map_err(std::io::Error::other)
            .and_then(|line| {
                use std::io::Write;
                let mut f = std::fs::OpenOptions::new().create(true).append(true).open(path)?;
                // One write per line: a restarted node's lines follow its previous runs'.
                f.write_all(format!("{line}\n").as_bytes())
            });
        if let Err(e) = written {
            tracing::warn!(path = %path.display(), error = %e, "cannot write the exit summary");
        }
    }
}

/// The simulated network of `ocelli sim` and `ocelli replay RECORDING`.
#[derive(clap::Args, Debug, Clone)]
#[command(next_help_heading = "Simulated network")]
pub struct NetArgs {
    /// One-way network latency, ms.
    #[arg(long, default_value_t = 2.0, value_parser = non_negative)]
    pub latency_ms: f64,
    /// Uniform latency jitter, ms.
    #[arg(long, default_value_t = 1.0, value_parser = non_negative)]
    pub jitter_ms: f64,
    /// Message loss probability, in [0, 1].
    #[arg(long, default_value_t = 0.0, value_parser = probability)]
    pub loss: f64,
    /// Largest per-node clock offset, ms.
    #[arg(long, default_value_t = 20.0, value_parser = non_negative)]
    pub clock_offset_ms: f64,
    /// Largest per-node clock drift, ppm.
    #[arg(long, default_value_t = 50.0, value_parser = non_negative)]
    pub clock_drift_ppm: f64,
}

impl NetArgs {
    pub fn model(&self) -> sim::net::NetworkModel {
        sim::net::NetworkModel {
            latency_ms: self.latency_ms,
            jitter_ms: self.jitter_ms,
            loss: self.loss,
            clock_offset_ms: self.clock_offset_ms,
            clock_drift_ppm: self.clock_drift_ppm,
            partitions: Vec::new(),
        }
    }
}

/// The flag's transport, else the scenario's.
pub fn transport_or_scenario(arg: Option<TransportArg>, scenario: &Scenario) -> TransportKind {
    arg.map_or(scenario.network.transport, TransportArg::kind)
}

/// The scenario file, or the embedded default when none is given.
///
/// # Errors
/// The file cannot be read or is not a valid scenario (the message names the field).
pub fn load_scenario(path: Option<&PathBuf>) -> Result<Scenario> {
    Ok(match path {
        Some(p) => Scenario::load(p)?,
        None => Scenario::default_scenario(),
    })
}

/// The scenario's node `id`, which must have `role`: a process started with another role's id
/// would join the cluster as something it is not.
///
/// # Errors
/// No such node, or a node of another role, naming the id, its role and the scenario.
pub fn node_of_role(scenario: &Scenario, id: u32, role: proto::scenario::NodeRole) -> Result<()> {
    use proto::scenario::NodeRole;
    let name = |r: NodeRole| match r {
        NodeRole::Camera => "camera",
        NodeRole::Head => "head",
        NodeRole::Server => "server",
        NodeRole::Acoustic => "acoustic",
    };
    match scenario.node(id) {
        None => anyhow::bail!(
            "--id {id}: scenario {} has no node {id} (its {}s: {})",
            scenario.name,
            name(role),
            scenario
                .nodes
                .iter()
                .filter(|n| n.role == role)
                .map(|n| n.id.to_string())
                .collect::<Vec<_>>()
                .join(", ")
        ),
        Some(n) if n.role != role => anyhow::bail!(
            "--id {id}: node {id} of scenario {} is a {}, not a {}",
            scenario.name,
            name(n.role),
            name(role)
        ),
        Some(_) => Ok(()),
    }
}

/// Warn about what a reader of a recording had to skip, in the same words for `report`,
/// `export` and `replay`.
pub fn warn_damage(path: &std::path::Path, loaded: &node_server::analysis::Loaded) {
    for line in lab::report::damage(loaded) {
        tracing::warn!(recording = %path.display(), "{line}");
    }
}

/// Ctrl-C, SIGTERM or SIGHUP (the launcher's supervisor and systemd stop nodes with SIGTERM;
/// a closed terminal sends SIGHUP).
pub async fn stop_signal() {
    use tokio::signal::unix::{SignalKind, signal};
    match (signal(SignalKind::terminate()), signal(SignalKind::hangup())) {
        (Ok(mut term), Ok(mut hup)) => {
            tokio::select! {
                _ = tokio::signal::ctrl_c() => {}
                _ = term.recv() => {}
                _ = hup.recv() => {}
            }
        }
        _ => {
            let _ = tokio::signal::ctrl_c().await;
        }
    }
}

/// Run one node process: a tokio runtime, the node's future `run(shutdown)`, and the stop
/// signals — the first cancels `shutdown` (the node stops cleanly), a second aborts.
///
/// # Errors
/// The runtime cannot start, or the node's own error.
pub fn run_node<T, F, Fut>(run: F) -> Result<T>
where
    F: FnOnce(tokio_util::sync::CancellationToken) -> Fut,
    Fut: std::future::Future<Output = Result<T>>,
{
    let rt = tokio::runtime::Builder::new_multi_thread()
        .worker_threads(2)
        .enable_all()
        .build()
        .map_err(|e| anyhow::anyhow!("cannot start the tokio runtime: {e}"))?;
    rt.block_on(async move {
        let shutdown = tokio_util::sync::CancellationToken::new();
        let token = shutdown.clone();
        tokio::spawn(async move {
            stop_signal().await;
            tracing::info!("stopping (a second signal aborts)");
            token.cancel();
            stop_signal().await;
            eprintln!("second signal: aborting");
            std::process::exit(130);
        });
        run(shutdown).await
    })
}
