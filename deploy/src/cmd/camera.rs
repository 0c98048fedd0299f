//! `ocelli camera --scenario FILE --id N [--transport ipc|tcp]`: run one camera node as a
//! process (node-camera's `process::run`) until SIGINT/SIGTERM; a second signal aborts.
//!
//! Cluster time is the host's wall clock (ns since the Unix epoch), so processes on one host
//! agree without sync; the synthetic world's t = 0 is `--epoch-ns` (default: start of this
//! process), which `launch` sets to the same value for every camera.

use super::common::{TransportArg, load_scenario, transport_or_scenario};
use anyhow::{Context, Result, bail};
use node_camera::process::{ProcessConfig, SourceSpec, run, transport_config};
use proto::ClusterTime;
use proto::sensor::ReferencePoint;
use std::path::PathBuf;
use std::process::ExitCode;
use std::sync::Arc;
use std::time::Duration;
use tokio_util::sync::CancellationToken;

/// Seed of a camera's synthetic world unless `--seed` says otherwise (every camera of a launch
/// shares it).
pub const SYNTHETIC_SEED: u64 = 1;

#[derive(clap::Args, Debug)]
pub struct Args {
    /// Scenario file (default: the embedded default scenario).
    #[arg(long)]
    pub scenario: Option<PathBuf>,
    /// This camera's node id.
    #[arg(long)]
    pub id: u32,
    /// Transport (default: the scenario's `network.transport`).
    #[arg(long, value_enum)]
    pub transport: Option<TransportArg>,
    /// Frame source: `synthetic`, `images:DIR`, `images:DIR:MANIFEST` or `v4l2:DEVICE`.
    #[arg(long, default_value = "synthetic")]
    pub source: String,
    /// Seed of the synthetic world (noise, multipath).
    #[arg(long, default_value_t = SYNTHETIC_SEED)]
    pub seed: u64,
    /// Cluster time (ns since the Unix epoch) of scenario time 0.
    #[arg(long)]
    pub epoch_ns: Option<i64>,
    /// The region point that stands for the target: its centre (solids) or foot (people).
    #[arg(long, value_enum, default_value_t = Reference::Centre)]
    pub reference: Reference,
    /// A logging run: measure every frame whatever the mode and send its measurements to the
    /// server's recording (for `ocelli replay`).
    #[arg(long)]
    pub record_measurements: bool,
}

#[derive(clap::ValueEnum, Clone, Copy, Debug, PartialEq, Eq)]
pub enum Reference {
    Centre,
    Foot,
}

fn parse_source(s: &str) -> Result<SourceSpec> {
    if s == "synthetic" {
        return Ok(SourceSpec::Synthetic);
    }
    if let Some(rest) = s.strip_prefix("images:") {
        let mut parts = rest.splitn(2, ':');
        let dir = PathBuf::from(parts.next().unwrap_or_default());
        let manifest = parts.next().map(PathBuf::from);
        return Ok(SourceSpec::Images { dir, manifest });
    }
    if let Some(dev) = s.strip_prefix("v4l2:") {
        #[cfg(feature = "v4l2")]
        return Ok(SourceSpec::V4l2 { device: dev.into() });
        #[cfg(not(feature = "v4l2"))]
        bail!("{dev}: this build has no V4L2 support (build with --features node-camera/v4l2)");
    }
    bail!("unknown --source {s:?}: expected synthetic, images:DIR[:MANIFEST] or v4l2:DEVICE")
}

pub fn run_cmd(args: Args) -> Result<ExitCode> {
    let scenario = load_scenario(args.scenario.as_ref())?;
    let kind = transport_or_scenario(args.transport, &scenario);
    let source = parse_source(&args.source)?;
    #[allow(clippy::disallowed_methods)] // the process runtime owns the clock
    let clock: runtime::transport::Clock = Arc::new(ClusterTime::wall_clock);
    let transport = transport_config(&scenario, args.id, kind, clock.clone())?;
    let cfg = ProcessConfig {
        scenario,
        id: args.id,
        transport,
        source,
        seed: args.seed,
        epoch: args.epoch_ns.map_or_else(|| clock(), ClusterTime),
        clock,
        tick: Duration::from_millis(100),
        reference: match args.reference {
            Reference::Centre => ReferencePoint::Centre,
            Reference::Foot => ReferencePoint::Foot,
        },
        record_measurements: args.record_measurements,
    };
    let rt = tokio::runtime::Builder::new_multi_thread()
        .worker_threads(2)
        .enable_all()
        .build()
        .context("tokio runtime")?;
    rt.block_on(async move {
        let stop = CancellationToken::new();
        let signals = stop.clone();
        tokio::spawn(async move {
            let mut term = match tokio::signal::unix::signal(tokio::signal::unix::SignalKind::terminate()) {
                Ok(s) => s,
                Err(e) => {
                    tracing::warn!(error = %e, "no SIGTERM handler");
                    return;
                }
            };
            tokio::select! {
                _ = tokio::signal::ctrl_c() => {}
                _ = term.recv() => {}
            }
            tracing::info!("stopping (signal again to abort)");
            signals.cancel();
            tokio::select! {
                _ = tokio::signal::ctrl_c() => {}
                _ = term.recv() => {}
            }
            std::process::exit(130);
        });
        let summary = run(cfg, stop).await?;
        println!(
            "{}",
            serde_json::json!({
                "event": "stopped",
                "frames": summary.counters.frames,
                "detections": summary.counters.detections,
                "contributions": summary.counters.contributions,
                "measurements": summary.counters.measurements,
                "dropped": summary.counters.dropped,
                "rejected": summary.counters.rejected,
                "still_unassociated": summary.counters.still_unassociated,
                "frames_lost": summary.frames_lost,
                "send_failures": summary.send_failures,
                "measured_frames": summary.logged.frames,
                "measured_dropped": summary.measured_dropped,
                "transport": summary.transport,
            })
        );
        Ok(ExitCode::SUCCESS)
    })
}
