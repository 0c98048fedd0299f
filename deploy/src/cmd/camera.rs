//! `ocelli camera --scenario FILE --id N [--transport ipc|tcp]`: run one camera node as a
//! process (node-camera's `process::run`) until SIGINT/SIGTERM; a second signal aborts.
//!
//! Cluster time is the host's wall clock (ns since the Unix epoch), so processes on one host
//! agree without sync; the synthetic world's t = 0 is `--epoch-ns` (default: start of this
//! process), which `launch` sets to the same value for every camera.

use super::common::{
    ExitSummaryArg, ScenarioArg, SecurityArgs, TransportArg, node_of_role, run_node, transport_or_scenario,
};
use anyhow::{Result, bail};
use node_camera::process::{OpenFrames, ProcessConfig, run};
use node_camera::source_spec::{Count, SharedStats, SourceSpec, SourceStats, SpecError, open_source};
use proto::scenario::Scenario;
use proto::sensor::{Frame, FrameSource, RadioSource, ReferencePoint, SourceError};
use proto::{ClusterTime, NodeId};
use runtime::HostClock;
use runtime::config::transport_config;
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
    #[command(flatten)]
    pub security: SecurityArgs,
    #[command(flatten)]
    pub exit: ExitSummaryArg,
    /// Frame source (see `node_camera::source_spec`): `synthetic`, `images:DIR[?manifest=FILE][&loop]`, `v4l2:/dev/videoN`,
    /// `file:PATH[?loop]`, `rtsp://…`, `http://…` (MJPEG) or `libcamera[:NAME]` (the last four
    /// need the `gstreamer` feature).
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
    /// Radio: `ble`, `ble:ADAPTER` or `file:PATH.mbd@SENSOR-MAC` (default: the scenario node's
    /// `radio`, else the synthetic world's with `--source synthetic`).
    #[arg(long, value_parser = proto::scenario::RadioSpec::parse)]
    pub radio: Option<proto::scenario::RadioSpec>,
}

#[derive(clap::ValueEnum, Clone, Copy, Debug, PartialEq, Eq)]
pub enum Reference {
    Centre,
    Foot,
}

/// A camera's frames, its radio (synthetic only) and its source's counters (real sources).
type Sources = (
    OpenFrames,
    Option<Box<dyn RadioSource + Send>>,
    Option<SharedStats>,
);

/// The camera's sources: a real camera is given its device, files or stream (opened through
/// [`open_source`], whose counters are returned); `synthetic` injects the simulated world's
/// frames and radio (what `ocelli launch` runs).
fn sources(spec: SourceSpec, scenario: &Scenario, id: u32, seed: u64, epoch: ClusterTime) -> Result<Sources> {
    if spec == SourceSpec::Synthetic {
        let frames = world::sources::SyntheticFrames::new(scenario, id, seed, epoch)?;
        let radio = world::sources::SyntheticRadio::new(scenario, id, seed, epoch)?;
        let open: OpenFrames = Box::new(move || Ok(Box::new(frames) as Box<dyn FrameSource>));
        return Ok((open, Some(Box::new(radio)), None));
    }
    if let Some(feature) = spec.missing_feature() {
        bail!(SpecError::NotBuilt {
            spec: spec.to_string(),
            feature
        });
    }
    let fps = scenario
        .node(id)
        .and_then(|n| n.camera.as_ref())
        .map_or(5.0, |c| c.fps);
    let k = scenario.camera_model(id)?.intrinsics;
    let shared = SharedStats::default();
    let counted = shared.clone();
    let open: OpenFrames = Box::new(move || {
        let opened = open_source(&spec, k.width, k.height, fps).map_err(|e| match e {
            SpecError::Open(e) => e,
            other => SourceError::Device(other.to_string()),
        })?;
        // The opened source counts into its own stats; the summary reads them through a
        // forwarding handle.
        Ok(Box::new(Forward {
            inner: opened.source,
            from: opened.stats,
            to: counted,
            seen: SourceStats::default(),
        }) as Box<dyn FrameSource>)
    });
    Ok((open, None, Some(shared)))
}

/// Copies a source's counters into the handle the CLI keeps after each capture.
struct Forward {
    inner: Box<dyn FrameSource>,
    from: SharedStats,
    to: SharedStats,
    seen: SourceStats,
}

impl FrameSource for Forward {
    fn size(&self) -> (u32, u32) {
        self.inner.size()
    }

    fn capture(&mut self, now: ClusterTime, frame: &mut Frame) -> Result<bool, SourceError> {
        let got = self.inner.capture(now, frame);
        let s = self.from.snapshot();
        let d = |new: u64, old: u64| new.saturating_sub(old);
        for (what, new, old) in [
            (Count::Frame, s.frames, self.seen.frames),
            (Count::Error, s.errors, self.seen.errors),
            (Count::End, s.ends, self.seen.ends),
            (Count::Stall, s.stalls, self.seen.stalls),
            (Count::Reconnect, s.reconnects, self.seen.reconnects),
            (Count::CapsChange, s.caps_changes, self.seen.caps_changes),
            (Count::DecodeError, s.decode_errors, self.seen.decode_errors),
            (Count::StreamError, s.stream_errors, self.seen.stream_errors),
            (Count::CorruptFrame, s.corrupt_frames, self.seen.corrupt_frames),
        ] {
            if new > old {
                self.to.add(what, d(new, old));
            }
        }
        self.seen = s;
        got
    }
}

pub fn run_cmd(args: Args) -> Result<ExitCode> {
    let scenario = args.scenario.load()?;
    node_of_role(&scenario, args.id, proto::scenario::NodeRole::Camera)?;
    let kind = transport_or_scenario(args.transport, &scenario);
    let source = SourceSpec::parse(&args.source)?;
    let clock = HostClock::follower();
    let transport = transport_config(
        &scenario,
        NodeId(args.id),
        kind,
        &clock,
        None,
        &args.security.link_security(),
    )?;
    let epoch = args.epoch_ns.map_or_else(|| clock.now(), ClusterTime);
    let node = scenario.node(args.id);
    let (frames, radio, source_stats) = if node.is_some_and(|n| n.radio_only()) {
        // No camera: no frames (its core never captures).
        let none: OpenFrames =
            Box::new(|| Ok(Box::new(node_camera::radio::NoCamera) as Box<dyn FrameSource>));
        (none, None, None)
    } else {
        sources(source, &scenario, args.id, args.seed, epoch)?
    };
    let radio = match args.radio.as_ref().or(node.and_then(|n| n.radio.as_ref())) {
        Some(spec) => Some(super::radio::open(spec, &clock, epoch)?),
        None => radio,
    };
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
    args.exit.write(&summary.run);
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
            "ghosts": summary.counters.ghosts,
            "revealed_pixels": summary.counters.revealed_pixels,
            "particle": particle_json(&summary.counters.particle),
            "frames_lost": summary.frames_lost,
            "send_failures": summary.run.send_failures,
            "measured_frames": summary.logged.frames,
            "measured_dropped": summary.measured_dropped(),
            "transport": summary.run.transport,
            "source": source_stats.map(|s| s.snapshot()),
        })
    );
    Ok(ExitCode::SUCCESS)
}

/// The particle filters' counters for the stop line: what the filters did and the reports the
/// camera left out, by why (all zero for a segmentation camera).
fn particle_json(c: &node_camera::ground_people::ParticleCounters) -> serde_json::Value {
    let (t, w) = (&c.tracker, &c.withheld);
    serde_json::json!({
        "filters_started": t.started,
        "filters_destroyed": t.destroyed,
        "duplicates_eliminated": t.duplicates_eliminated,
        "refused_full": t.refused_full,
        "refused_fragments": t.refused_fragments,
        "withheld_walked_out": w.walked_out,
        "withheld_unsupported": w.unsupported,
        "withheld_hidden_feet": w.hidden_feet,
        "withheld_off_the_floor": w.off_the_floor,
    })
}
