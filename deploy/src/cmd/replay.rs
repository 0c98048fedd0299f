//! `ocelli replay`: estimates as JSON Lines on standard output, from either
//! - a logging run's recording (`ocelli replay RECORDING --fusion … --activation …`): its
//!   recorded camera measurements re-run through the heads with any method and policy
//!   ([`crate::replay::rerun`]), followed by the run report of the replay (`ocelli report`'s);
//! - external detections (`--detections FILE`, JSON Lines, any detector) through a fusion
//!   method, with cameras from a scenario (ids = node ids) or an OpenCV calibration folder (ids
//!   from the file names).

use super::common::NetArgs;
use crate::replay::cameras::Cameras;
use crate::replay::detections::read_detections;
use crate::replay::ml::{Estimate, MlOptions, replay_ml};
use crate::replay::rerun::{RerunOptions, recording_t0, rerun};
use crate::replay::track::{RssiNodes, TrackOptions, track_with_rssi};
use crate::sim::net::NetworkModel;
use crate::sim::runtime::SimOptions;
use anyhow::{Context, Result};
use node_server::export::{TrackRow, track_rows};
use node_server::report::Report;
use proto::ClusterTime;
use proto::scenario::{Activation, Fusion};
use std::io::{BufRead, BufReader, Write};
use std::path::PathBuf;
use std::process::ExitCode;

/// Fusion method of a replay.
#[derive(clap::ValueEnum, Clone, Copy, Debug, PartialEq, Eq)]
pub enum ReplayMethod {
    /// Paper 000's maximum-likelihood fusion: one estimate per person per `t`.
    Ml,
    /// ML estimates tracked by one EIF per target: adds a track id.
    Eif,
}

/// `--fusion` of a recording's replay.
#[derive(clap::ValueEnum, Clone, Copy, Debug, PartialEq, Eq)]
pub enum FusionArg {
    DistributedEif,
    CentralizedEif,
    Ml,
}

/// `--activation` of a recording's replay.
#[derive(clap::ValueEnum, Clone, Copy, Debug, PartialEq, Eq)]
pub enum ActivationArg {
    AllOn,
    CameraEntropy,
    FullNode,
    ThreeMode,
}

impl FusionArg {
    pub fn fusion(self) -> Fusion {
        match self {
            FusionArg::DistributedEif => Fusion::DistributedEif,
            FusionArg::CentralizedEif => Fusion::CentralizedEif,
            FusionArg::Ml => Fusion::Ml,
        }
    }
}

impl ActivationArg {
    pub fn activation(self) -> Activation {
        match self {
            ActivationArg::AllOn => Activation::AllOn,
            ActivationArg::CameraEntropy => Activation::CameraEntropy,
            ActivationArg::FullNode => Activation::FullNode,
            ActivationArg::ThreeMode => Activation::ThreeMode,
        }
    }
}

/// What only a recording's replay uses.
#[derive(clap::Args, Debug, Clone)]
pub struct RecordingArgs {
    /// Fusion method of the replay (default: the recorded scenario's).
    #[arg(long, value_enum)]
    pub fusion: Option<FusionArg>,
    /// Activation policy of the replay (default: the recorded scenario's).
    #[arg(long, value_enum)]
    pub activation: Option<ActivationArg>,
    /// Seed of the replay's simulated network and clocks (the run's, to reproduce it).
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    #[command(flatten)]
    pub net: NetArgs,
    /// No latency, jitter, loss or clock error (overrides the network flags).
    #[arg(long)]
    pub ideal_network: bool,
    /// The level the recording was made at: `pixel` (segmented frames, as `ocelli launch`
    /// records) or `measurement` (`ocelli sim --level measurement`). Cameras check segmented
    /// regions for motion before offering them for new tracks, so give the run's level to
    /// reproduce it.
    #[arg(long, value_enum, default_value = "pixel")]
    pub recorded_level: super::sim::LevelArg,
    /// Cluster time (ns) of scenario time 0 in the recording (default: its first record's
    /// time — 0 for `ocelli sim`, the server's start for `ocelli launch`).
    #[arg(long)]
    pub t0_ns: Option<i64>,
    /// Print the report as one JSON line (`{"report": …}`) after the estimates instead of a
    /// table on standard error.
    #[arg(long)]
    pub json: bool,
}

impl Default for RecordingArgs {
    /// The command line's defaults (for callers that build [`Args`] in code).
    fn default() -> Self {
        #[derive(clap::Parser)]
        struct Only {
            #[command(flatten)]
            rec: RecordingArgs,
        }
        <Only as clap::Parser>::parse_from(["replay"]).rec
    }
}

#[derive(clap::Args, Debug)]
#[command(group(clap::ArgGroup::new("input").required(true).args(["recording", "detections"])))]
pub struct Args {
    /// A logging run's recording (`ocelli sim --record-measurements --record FILE`, or
    /// `ocelli launch --record-measurements`) to re-run through the heads.
    pub recording: Option<PathBuf>,
    /// JSON Lines detections, `-` for standard input.
    #[arg(long)]
    pub detections: Option<String>,
    /// Cameras from this scenario (detections name cameras by node id); with a recording,
    /// replaces the recorded scenario.
    #[arg(long)]
    pub scenario: Option<PathBuf>,
    /// Cameras from an OpenCV calibration folder (`intrinsic/intr_<ID>.xml`,
    /// `extrinsic/extr_<ID>.xml`).
    #[arg(long)]
    pub opencv_calibration: Option<PathBuf>,
    /// Image size `WIDTHxHEIGHT` for OpenCV files that do not state it.
    #[arg(long, default_value = "1920x1080", value_parser = parse_size)]
    pub image_size: (u32, u32),
    #[arg(long, value_enum, default_value = "ml")]
    pub method: ReplayMethod,
    /// Targets move on the plane z = H (m), e.g. 0 for people's foot points.
    #[arg(long)]
    pub plane_z: Option<f64>,
    /// Pixel noise of a detection (px).
    #[arg(long, default_value_t = 2.0)]
    pub pixel_sigma: f64,
    /// Largest ground distance (m) between two cameras' views of one person.
    #[arg(long, default_value_t = 1.0)]
    pub gate: f64,
    /// Report only people seen by at least this many cameras.
    #[arg(long, default_value_t = 1)]
    pub min_cameras: usize,
    #[command(flatten)]
    pub rec: RecordingArgs,
}

fn parse_size(s: &str) -> Result<(u32, u32), String> {
    let (w, h) = s
        .split_once('x')
        .ok_or_else(|| format!("`{s}`: expected WIDTHxHEIGHT"))?;
    let n = |x: &str| {
        x.parse::<u32>()
            .ok()
            .filter(|v| *v > 0)
            .ok_or_else(|| format!("`{s}`: `{x}` is not a positive whole number"))
    };
    Ok((n(w)?, n(h)?))
}

/// Load cameras and detections, fuse, and return the estimates (the library entry point).
///
/// # Errors
/// Unreadable or malformed cameras or detections, or invalid options.
pub fn replay(args: &Args, input: impl BufRead) -> Result<Vec<Estimate>> {
    anyhow::ensure!(
        args.pixel_sigma.is_finite() && args.pixel_sigma > 0.0,
        "--pixel-sigma {} must be a positive number",
        args.pixel_sigma
    );
    anyhow::ensure!(
        args.gate.is_finite() && args.gate > 0.0,
        "--gate {} must be a positive number",
        args.gate
    );
    if let Some(h) = args.plane_z {
        anyhow::ensure!(h.is_finite(), "--plane-z {h} must be finite");
    }
    let (cameras, motion, rssi_model) = match (&args.scenario, &args.opencv_calibration) {
        (Some(path), _) => {
            let scenario = proto::scenario::Scenario::load(path)?;
            (
                Cameras::from_scenario(&scenario)?,
                scenario.method.motion,
                scenario.method.rssi_default,
            )
        }
        (None, Some(dir)) => (
            Cameras::from_opencv_dir(dir, Some(args.image_size))?,
            proto::models::MotionModel::default(),
            proto::models::RssiModel::default(),
        ),
        (None, None) => anyhow::bail!("give --scenario or --opencv-calibration"),
    };
    let detections = read_detections(input).context("reading detections")?;
    let options = MlOptions {
        plane_z: args.plane_z,
        pixel_sigma: args.pixel_sigma,
        gate_m: args.gate,
        min_cameras: args.min_cameras,
        ..MlOptions::default()
    };
    let (estimates, skipped) = replay_ml(&detections, &cameras, &options);
    tracing::info!(
        detections = detections.len(),
        estimates = estimates.len(),
        ?skipped,
        "ML fusion done"
    );
    Ok(match args.method {
        ReplayMethod::Ml => estimates,
        ReplayMethod::Eif => {
            // A detection's RSSI names a node; camera nodes carry the radios, so a node's
            // position is its camera's centre.
            let nodes = RssiNodes {
                positions: cameras
                    .models
                    .iter()
                    .map(|(id, m)| (id.clone(), cameras.to_user(&m.pose.centre())))
                    .collect(),
                model: rssi_model,
            };
            let (tracked, counts) = track_with_rssi(
                &estimates,
                &TrackOptions {
                    motion,
                    ..TrackOptions::default()
                },
                &nodes,
            );
            tracing::info!(tracked = tracked.len(), ?counts, "EIF tracking done");
            if counts.rssi_unknown_node > 0 {
                tracing::warn!(
                    readings = counts.rssi_unknown_node,
                    "RSSI readings from nodes that are not cameras of the replay, not used"
                );
            }
            tracked
        }
    })
}

/// Re-run a recording's measurements through the heads: the replay's owner track rows (one per
/// global track and step) and its report.
///
/// # Errors
/// An unreadable recording or scenario, or a recording without measurements.
pub fn replay_recording(path: &std::path::Path, args: &Args) -> Result<(Vec<TrackRow>, Report)> {
    let scenario = args
        .scenario
        .as_deref()
        .map(proto::scenario::Scenario::load)
        .transpose()?;
    let loaded =
        node_server::replay::load(path, scenario).with_context(|| format!("reading {}", path.display()))?;
    for s in &loaded.skipped {
        tracing::warn!(
            offset = s.offset,
            bytes = s.bytes,
            damage = ?s.damage,
            "replay: damaged stretch of the recording skipped"
        );
    }
    let rec = &args.rec;
    let network = if rec.ideal_network {
        NetworkModel::default()
    } else {
        rec.net.model()
    };
    let opts = RerunOptions {
        fusion: rec.fusion.map(FusionArg::fusion),
        activation: rec.activation.map(ActivationArg::activation),
        sim: SimOptions {
            seed: rec.seed,
            network,
            level: match rec.recorded_level {
                super::sim::LevelArg::Pixel => crate::sim::runtime::Level::Pixel,
                super::sim::LevelArg::Measurement => crate::sim::runtime::Level::Measurement,
            },
            ..SimOptions::default()
        },
        t0: rec.t0_ns.map_or_else(|| recording_t0(&loaded), ClusterTime),
    };
    let replay = rerun(&loaded, &opts)?;
    tracing::info!(
        frames = replay.frames,
        unknown_camera_frames = replay.unknown_camera_frames,
        superseded_frames = replay.superseded_frames,
        fusion = ?replay.scenario.method.fusion,
        activation = ?replay.scenario.method.activation,
        "replay done"
    );
    let replayed = replay.loaded();
    let rows = track_rows(&replayed).into_iter().filter(|r| r.owner).collect();
    // The replay's records are on its own virtual clock, where scenario time 0 is 0.
    Ok((rows, node_server::report::compute(&replayed, ClusterTime(0))))
}

fn write_lines<T: serde::Serialize>(items: &[T], out: &mut impl Write) -> Result<bool> {
    for e in items {
        let line = serde_json::to_string(e)?;
        match writeln!(out, "{line}") {
            Err(e) if e.kind() == std::io::ErrorKind::BrokenPipe => return Ok(false),
            other => other?,
        }
    }
    Ok(true)
}

pub fn run(args: Args) -> Result<ExitCode> {
    let stdout = std::io::stdout();
    let mut out = std::io::BufWriter::new(stdout.lock());
    if let Some(path) = &args.recording {
        let (rows, report) = replay_recording(path, &args)?;
        if !write_lines(&rows, &mut out)? {
            return Ok(ExitCode::SUCCESS);
        }
        if args.rec.json {
            write_lines(&[serde_json::json!({ "report": report })], &mut out)?;
        } else {
            eprint!("{}", report.to_table());
        }
    } else {
        let estimates = match args.detections.as_deref() {
            Some("-") | None => replay(&args, std::io::stdin().lock())?,
            Some(p) => {
                let file = std::fs::File::open(p).with_context(|| format!("cannot open {p}"))?;
                replay(&args, BufReader::new(file))?
            }
        };
        if !write_lines(&estimates, &mut out)? {
            return Ok(ExitCode::SUCCESS);
        }
    }
    match out.flush() {
        Err(e) if e.kind() == std::io::ErrorKind::BrokenPipe => Ok(ExitCode::SUCCESS),
        other => other.map(|()| ExitCode::SUCCESS).map_err(Into::into),
    }
}
