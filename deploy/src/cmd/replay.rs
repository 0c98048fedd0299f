//! `ocelli replay`: estimates as JSON Lines on standard output, from either
//! - a logging run's recording (`ocelli replay RECORDING --fusion … --activation …`): its
//!   recorded camera measurements re-run through the heads with any method and policy
//!   (`lab::replay::rerun`), followed by the run report of the replay (`ocelli report`'s);
//! - external detections (`--detections FILE`, JSON Lines, any detector) through a fusion
//!   method, with cameras from a scenario (ids = node ids) or an OpenCV calibration folder (ids
//!   from the file names).

use super::common::NetArgs;
use anyhow::{Context, Result};
use lab::replay::fuse::{CameraSource, FuseMethod, FuseOptions, fuse};
use lab::replay::rerun::{RerunOptions, recording_t0, replay_recording};
use proto::ClusterTime;
use proto::scenario::{Activation, Fusion};
use sim::SimOptions;
use sim::net::NetworkModel;
use std::io::{BufReader, Write};
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

impl Args {
    /// The fusion options these flags ask for.
    ///
    /// # Errors
    /// Neither `--scenario` nor `--opencv-calibration`.
    pub fn fuse_options(&self) -> Result<FuseOptions> {
        let cameras = match (&self.scenario, &self.opencv_calibration) {
            (Some(path), _) => CameraSource::Scenario(path.clone()),
            (None, Some(dir)) => CameraSource::OpenCv {
                dir: dir.clone(),
                image_size: self.image_size,
            },
            (None, None) => anyhow::bail!("give --scenario or --opencv-calibration"),
        };
        Ok(FuseOptions {
            cameras,
            method: match self.method {
                ReplayMethod::Ml => FuseMethod::Ml,
                ReplayMethod::Eif => FuseMethod::Eif,
            },
            plane_z: self.plane_z,
            pixel_sigma: self.pixel_sigma,
            gate: self.gate,
            min_cameras: self.min_cameras,
        })
    }

    /// The re-run options these flags ask for, for a loaded recording.
    fn rerun_options(&self, loaded: &node_server::analysis::Loaded) -> RerunOptions {
        let rec = &self.rec;
        let network = if rec.ideal_network {
            NetworkModel::default()
        } else {
            rec.net.model()
        };
        RerunOptions {
            fusion: rec.fusion.map(FusionArg::fusion),
            activation: rec.activation.map(ActivationArg::activation),
            sim: SimOptions {
                seed: rec.seed,
                network,
                level: rec.recorded_level.level(),
                ..SimOptions::default()
            },
            t0: rec.t0_ns.map_or_else(|| recording_t0(loaded), ClusterTime),
        }
    }
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
        let scenario = args
            .scenario
            .as_deref()
            .map(proto::scenario::Scenario::load)
            .transpose()?;
        let (rows, report) = replay_recording(path, scenario, |loaded| args.rerun_options(loaded))?;
        if !write_lines(&rows, &mut out)? {
            return Ok(ExitCode::SUCCESS);
        }
        if args.rec.json {
            write_lines(&[serde_json::json!({ "report": report })], &mut out)?;
        } else {
            eprint!("{}", report.to_table());
        }
    } else {
        let opts = args.fuse_options()?;
        let estimates = match args.detections.as_deref() {
            Some("-") | None => fuse(&opts, std::io::stdin().lock())?,
            Some(p) => {
                let file = std::fs::File::open(p).with_context(|| format!("cannot open {p}"))?;
                fuse(&opts, BufReader::new(file))?
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
