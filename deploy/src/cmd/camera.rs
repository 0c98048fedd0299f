//! `ocelli camera --scenario FILE --id N [--transport ipc|tcp]`: run one camera node as a
//! process (node-camera's `process::run`) until SIGINT/SIGTERM; a second signal aborts.
//!
//! Cluster time is the host's wall clock (ns since the Unix epoch), so processes on one host
//! agree without sync; the synthetic world's t = 0 is `--epoch-ns` (default: start of this
//! process), which `launch` sets to the same value for every camera.

use super::common::{ScenarioArg, TransportArg, node_of_role, run_node, transport_or_scenario};
use anyhow::{Result, bail};
use node_camera::process::{OpenFrames, ProcessConfig, run};
use node_camera::source::ImageSequence;
use proto::scenario::Scenario;
use proto::sensor::{FrameSource, RadioSource, ReferencePoint};
use proto::{ClusterTime, NodeId};
use runtime::HostClock;
use runtime::config::transport_config;
use std::path::PathBuf;
use std::process::ExitCode;
use std::time::Duration;

/// Seed of a camera's synthetic world unless `--seed` says otherwise (every camera of a launch
/// shares it).
pub const SYNTHETIC_SEED: u64 = 1;

#[derive(clap::Args, Debug)]
pub struct Args {
    #[command(flatten)]
    pub scenario: ScenarioArg,
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

/// Where a camera's frames come from.
#[derive(Clone, Debug)]
enum SourceSpec {
    /// The scenario's simulated world (frames and radio).
    Synthetic,
    /// A directory of PNG/JPEG frames, at the camera's rate or with a manifest; loops.
    Images { dir: PathBuf, manifest: Option<PathBuf> },
    /// A V4L2 device.
    #[cfg(feature = "v4l2")]
    V4l2 { device: String },
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

/// The camera's sources: a real camera is given its device or files; `synthetic` injects the
/// simulated world's frames and radio (what `ocelli launch` runs).
fn sources(
    spec: SourceSpec,
    scenario: &Scenario,
    id: u32,
    seed: u64,
    epoch: ClusterTime,
) -> Result<(OpenFrames, Option<Box<dyn RadioSource + Send>>)> {
    let fps = scenario
        .node(id)
        .and_then(|n| n.camera.as_ref())
        .map_or(5.0, |c| c.fps);
    Ok(match spec {
        SourceSpec::Synthetic => {
            let frames = world::sources::SyntheticFrames::new(scenario, id, seed, epoch)?;
            let radio = world::sources::SyntheticRadio::new(scenario, id, seed, epoch)?;
            let open: OpenFrames = Box::new(move || Ok(Box::new(frames) as Box<dyn FrameSource>));
            (open, Some(Box::new(radio)))
        }
        SourceSpec::Images { dir, manifest } => {
            let open: OpenFrames = Box::new(move || {
                let seq = match manifest {
                    Some(m) => ImageSequence::with_manifest(&dir, &m)?,
                    None => ImageSequence::with_rate(&dir, fps)?,
                };
                Ok(Box::new(seq.looping(true)) as Box<dyn FrameSource>)
            });
            (open, None)
        }
        #[cfg(feature = "v4l2")]
        SourceSpec::V4l2 { device } => {
            let k = scenario.camera_model(id)?.intrinsics;
            let open: OpenFrames = Box::new(move || {
                Ok(Box::new(node_camera::v4l2::V4l2Source::open(
                    &device, k.width, k.height, fps,
                )?) as Box<dyn FrameSource>)
            });
            (open, None)
        }
    })
}

pub fn run_cmd(args: Args) -> Result<ExitCode> {
    let scenario = args.scenario.load()?;
    node_of_role(&scenario, args.id, proto::scenario::NodeRole::Camera)?;
    let kind = transport_or_scenario(args.transport, &scenario);
    let source = parse_source(&args.source)?;
    let clock = HostClock::follower();
    let transport = transport_config(&scenario, NodeId(args.id), kind, &clock, None)?;
    let epoch = args.epoch_ns.map_or_else(|| clock.now(), ClusterTime);
    let (frames, radio) = sources(source, &scenario, args.id, args.seed, epoch)?;
    let leader = scenario.server().map(|s| NodeId(s.id));
    let cfg = ProcessConfig {
        id: args.id,
        process: runtime::ProcessConfig::new(transport, leader, Duration::from_millis(100)),
        frames,
        radio,
        reference: match args.reference {
            Reference::Centre => ReferencePoint::Centre,
            Reference::Foot => ReferencePoint::Foot,
        },
        record_measurements: args.record_measurements,
        scenario,
    };
    let summary = run_node(|shutdown| async move { Ok(run(cfg, clock, shutdown).await?) })?;
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
            "send_failures": summary.run.send_failures,
            "measured_frames": summary.logged.frames,
            "measured_dropped": summary.measured_dropped(),
            "transport": summary.run.transport,
        })
    );
    Ok(ExitCode::SUCCESS)
}
