//! `ocelli view RECORDING`: a server's recording played back in the viewer's pages, with play,
//! pause, a time slider and speed (paper 004's log playback).

use super::common::{ScenarioArg, run_node};
use anyhow::{Context, Result};
use std::net::SocketAddr;
use std::path::PathBuf;
use std::process::ExitCode;
use std::time::Duration;

#[derive(clap::Args, Debug)]
pub struct Args {
    /// The server's recording file.
    #[arg(value_name = "RECORDING")]
    pub recording: PathBuf,
    /// Serve HTTP here.
    #[arg(long, default_value = super::viewer::DEFAULT_LISTEN)]
    pub listen: SocketAddr,
    /// A scenario whose `[world.geo]` places a recording that has none on Earth.
    #[command(flatten)]
    pub scenario: ScenarioArg,
}

pub fn run(args: Args) -> Result<ExitCode> {
    let geo = args.scenario.load_given()?.and_then(|s| s.world.geo);
    let (recording, listen) = (args.recording, args.listen);
    run_node(|shutdown| async move {
        let listener = tokio::net::TcpListener::bind(listen)
            .await
            .with_context(|| format!("cannot listen on {listen}"))?;
        eprintln!(
            "viewer: http://{} playing {}",
            listener.local_addr()?,
            recording.display()
        );
        view::serve_recording(&recording, geo, listener, Duration::from_millis(200), shutdown)
            .await
            .with_context(|| format!("playing {}", recording.display()))?;
        Ok(())
    })?;
    Ok(ExitCode::SUCCESS)
}
