//! `ocelli fuse DETECTIONS`: external detections from any detector (JSON Lines) fused into
//! estimates, printed as JSON Lines — cameras from a scenario (detections name cameras by node
//! id) or an OpenCV calibration folder (ids from the file names). See `lab::replay::fuse`.
//!
//! External detections are fused, not replayed: `ocelli replay` re-runs a recording.

use super::common::{ScenarioArg, finite, positive};
use anyhow::{Context, Result};
use lab::replay::fuse::{CameraSource, FuseMethod, FuseOptions, fuse_all};
use lab::replay::ml::{FOOT_POINT_SIGMA_M, ViewNoise};
use std::io::{BufReader, Write};
use std::path::PathBuf;
use std::process::ExitCode;

/// Fusion method.
#[derive(clap::ValueEnum, Clone, Copy, Debug, PartialEq, Eq)]
pub enum MethodArg {
    /// Paper 000's maximum-likelihood fusion: one estimate per person per `t`.
    Ml,
    /// ML estimates tracked by one EIF per target: adds a track id.
    Eif,
}

#[derive(clap::Args, Debug)]
pub struct Args {
    /// JSON Lines detections (`{"t", "camera", "u", "v"}`, optional `"box"` and
    /// `"rssi": {"<node>": dBm}`); `-` for standard input.
    #[arg(value_name = "DETECTIONS")]
    pub detections: String,
    #[command(flatten)]
    pub scenario: ScenarioArg,
    /// Cameras from an OpenCV calibration folder (`intrinsic/intr_<ID>.xml`,
    /// `extrinsic/extr_<ID>.xml`) instead of a scenario.
    #[arg(long, value_name = "DIR", conflicts_with = "scenario")]
    pub opencv_calibration: Option<PathBuf>,
    /// Image size `WIDTHxHEIGHT` for OpenCV files that do not state it.
    #[arg(long, default_value = "1920x1080", value_parser = parse_size)]
    pub image_size: (u32, u32),
    #[arg(long, value_enum, default_value = "ml")]
    pub method: MethodArg,
    /// Targets move on the plane z = H (m), e.g. 0 for people's foot points. Without it a
    /// person needs two cameras at one time stamp.
    #[arg(long, value_parser = finite)]
    pub plane_z: Option<f64>,
    /// Pixel noise of a detection (px).
    #[arg(long, default_value_t = 2.0, value_parser = positive)]
    pub pixel_sigma: f64,
    /// Largest ground distance (m) between two cameras' views of one person.
    #[arg(long, default_value_t = 1.0, value_parser = positive)]
    pub gate: f64,
    /// Report only people seen by at least this many cameras.
    #[arg(long, default_value_t = 1, value_parser = clap::value_parser!(u32).range(1..=1000))]
    pub min_cameras: u32,
    /// With --plane-z: a view's ground error beyond its pixel noise — METRES for every view
    /// (default: a box-bottom foot point's), `estimated` from how the views of each camera
    /// disagree with the others, or `pixel` for none (detections that are exact projections).
    #[arg(long, default_value_t = FOOT_POINT_SIGMA_M.to_string(), value_parser = view_noise)]
    pub view_noise: String,
}

fn view_noise(s: &str) -> Result<String, String> {
    parse_view_noise(s).map(|_| s.to_string())
}

fn parse_view_noise(s: &str) -> Result<ViewNoise, String> {
    match s {
        "pixel" => Ok(ViewNoise::Pixel),
        "estimated" => Ok(ViewNoise::Estimated),
        m => super::common::non_negative(m)
            .map(ViewNoise::Fixed)
            .map_err(|e| format!("expected METRES, `estimated` or `pixel`: {e}")),
    }
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
        let cameras = match (&self.scenario.scenario, &self.opencv_calibration) {
            (Some(path), _) => CameraSource::Scenario(path.clone()),
            (None, Some(dir)) => CameraSource::OpenCv {
                dir: dir.clone(),
                image_size: self.image_size,
            },
            (None, None) => {
                anyhow::bail!("the cameras are missing: give --scenario FILE or --opencv-calibration DIR")
            }
        };
        Ok(FuseOptions {
            cameras,
            method: match self.method {
                MethodArg::Ml => FuseMethod::Ml,
                MethodArg::Eif => FuseMethod::Eif,
            },
            plane_z: self.plane_z,
            pixel_sigma: self.pixel_sigma,
            gate: self.gate,
            min_cameras: self.min_cameras as usize,
            view_noise: parse_view_noise(&self.view_noise).map_err(anyhow::Error::msg)?,
        })
    }
}

pub fn run(args: Args) -> Result<ExitCode> {
    let opts = args.fuse_options()?;
    let fused = match args.detections.as_str() {
        "-" => fuse_all(&opts, std::io::stdin().lock())?,
        p => {
            let file = std::fs::File::open(p).with_context(|| format!("cannot open {p}"))?;
            fuse_all(&opts, BufReader::new(file)).with_context(|| p.to_string())?
        }
    };
    tracing::info!(
        detections = fused.detections,
        skipped_lines = fused.skipped_lines.count,
        estimates = fused.estimates.len(),
        "fused"
    );
    let mut out = std::io::BufWriter::new(std::io::stdout().lock());
    for e in &fused.estimates {
        writeln!(out, "{}", serde_json::to_string(e)?)?;
    }
    out.flush()?;
    Ok(ExitCode::SUCCESS)
}
