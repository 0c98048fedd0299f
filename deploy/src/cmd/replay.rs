//! `ocelli replay RECORDING --fusion … --activation …`: a logging run's recorded camera
//! measurements re-run through the heads with any method and policy (`lab::replay::rerun`):
//! estimates as JSON Lines on standard output, then the run report of the replay (`ocelli
//! report`'s). External detections are fused, not replayed: that is `ocelli fuse`.

use super::common::{NetArgs, ScenarioArg, warn_damage};
use anyhow::{Context, Result};
use lab::replay::rerun::{RerunOptions, recording_t0, replay_recording};
use proto::ClusterTime;
use proto::scenario::{Activation, Fusion};
use sim::SimOptions;
use sim::net::NetworkModel;
use std::io::Write;
use std::path::PathBuf;
use std::process::ExitCode;

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
    /// Cluster time (ns) of scenario time 0 in the recording, and score the replay against the
    /// scenario's simulated targets from there (default: what the recording says — `ocelli
    /// sim` and `ocelli launch` record it; a real deployment's replay is not scored).
    #[arg(long, value_name = "NS")]
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
pub struct Args {
    /// A logging run's recording (`ocelli sim --record-measurements --record FILE`, or
    /// `ocelli launch --record-measurements`) to re-run through the heads.
    #[arg(value_name = "RECORDING", required_unless_present = "detections")]
    pub recording: Option<PathBuf>,
    /// Replaces the recorded scenario.
    #[command(flatten)]
    pub scenario: ScenarioArg,
    /// External detections are fused, not replayed: use `ocelli fuse DETECTIONS`.
    #[arg(long, hide = true, value_name = "FILE")]
    pub detections: Option<String>,
    #[command(flatten)]
    pub rec: RecordingArgs,
}

impl Args {
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
    if let Some(file) = &args.detections {
        anyhow::bail!(
            "external detections are fused, not replayed: run `ocelli fuse {file} --scenario FILE` (or --opencv-calibration DIR)"
        );
    }
    let recording = args.recording.as_deref().context("a recording is required")?;
    let stdout = std::io::stdout();
    let mut out = std::io::BufWriter::new(stdout.lock());
    let scenario = args.scenario.load_given()?;
    let given_t0 = args.rec.t0_ns.map(ClusterTime);
    let (rows, report) = replay_recording(recording, scenario, given_t0, |loaded| {
        warn_damage(recording, loaded);
        args.rerun_options(loaded)
    })?;
    if !write_lines(&rows, &mut out)? {
        return Ok(ExitCode::SUCCESS);
    }
    if args.rec.json {
        write_lines(&[serde_json::json!({ "report": report })], &mut out)?;
    } else {
        eprint!("{}", report.to_table());
    }
    match out.flush() {
        Err(e) if e.kind() == std::io::ErrorKind::BrokenPipe => Ok(ExitCode::SUCCESS),
        other => other.map(|()| ExitCode::SUCCESS).map_err(Into::into),
    }
}
