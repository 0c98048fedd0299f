//! What the node and cluster subcommands share: the transport flag, the scenario argument and
//! the stop signal.

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
