//! `ocelli replay`: external detections (JSON Lines, any detector) through a fusion method,
//! estimates as JSON Lines on standard output. Cameras come from a scenario (ids = node ids) or
//! an OpenCV calibration folder (ids from the file names). Recorded camera measurements are not
//! replayed: the server's recording holds tracks, not the cameras' measurements.

use crate::replay::cameras::Cameras;
use crate::replay::detections::read_detections;
use crate::replay::ml::{Estimate, MlOptions, replay_ml};
use crate::replay::track::{TrackOptions, track};
use anyhow::{Context, Result};
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

#[derive(clap::Args, Debug)]
#[command(group(clap::ArgGroup::new("cams").required(true).args(["scenario", "opencv_calibration"])))]
pub struct Args {
    /// JSON Lines detections, `-` for standard input.
    #[arg(long)]
    pub detections: String,
    /// Cameras from this scenario (detections name cameras by node id).
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
    let (cameras, motion) = match (&args.scenario, &args.opencv_calibration) {
        (Some(path), _) => {
            let scenario = proto::scenario::Scenario::load(path)?;
            (Cameras::from_scenario(&scenario)?, scenario.method.motion)
        }
        (None, Some(dir)) => (
            Cameras::from_opencv_dir(dir, Some(args.image_size))?,
            proto::models::MotionModel::default(),
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
            let (tracked, dropped) = track(
                &estimates,
                &TrackOptions {
                    motion,
                    ..TrackOptions::default()
                },
            );
            tracing::info!(tracked = tracked.len(), dropped, "EIF tracking done");
            tracked
        }
    })
}

pub fn run(args: Args) -> Result<ExitCode> {
    let estimates = if args.detections == "-" {
        replay(&args, std::io::stdin().lock())?
    } else {
        let file = std::fs::File::open(&args.detections)
            .with_context(|| format!("cannot open {}", args.detections))?;
        replay(&args, BufReader::new(file))?
    };
    let stdout = std::io::stdout();
    let mut out = std::io::BufWriter::new(stdout.lock());
    for e in &estimates {
        let line = serde_json::to_string(e)?;
        match writeln!(out, "{line}") {
            Err(e) if e.kind() == std::io::ErrorKind::BrokenPipe => return Ok(ExitCode::SUCCESS),
            other => other?,
        }
    }
    match out.flush() {
        Err(e) if e.kind() == std::io::ErrorKind::BrokenPipe => Ok(ExitCode::SUCCESS),
        other => other.map(|()| ExitCode::SUCCESS).map_err(Into::into),
    }
}
