//! What the node and cluster subcommands share: the transport flag, the scenario argument,
//! the simulated network's flags and the stop signal.

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

/// The simulated network of `ocelli sim` and `ocelli replay RECORDING`.
#[derive(clap::Args, Debug, Clone)]
pub struct NetArgs {
    /// One-way network latency, ms.
    #[arg(long, default_value_t = 2.0)]
    pub latency_ms: f64,
    /// Uniform latency jitter, ms.
    #[arg(long, default_value_t = 1.0)]
    pub jitter_ms: f64,
    /// Message loss probability.
    #[arg(long, default_value_t = 0.0)]
    pub loss: f64,
    /// Largest per-node clock offset, ms.
    #[arg(long, default_value_t = 20.0)]
    pub clock_offset_ms: f64,
    /// Largest per-node clock drift, ppm.
    #[arg(long, default_value_t = 50.0)]
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

/// Ctrl-C or SIGTERM (the launcher's supervisor and systemd stop nodes with SIGTERM).
pub async fn stop_signal() {
    use tokio::signal::unix::{SignalKind, signal};
    match signal(SignalKind::terminate()) {
        Ok(mut term) => {
            tokio::select! {
                _ = tokio::signal::ctrl_c() => {}
                _ = term.recv() => {}
            }
        }
        Err(_) => {
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
