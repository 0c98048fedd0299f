//! External detections from any detector (JSON Lines) fused into estimates: cameras from a
//! scenario or an OpenCV calibration folder, paper 000's ML fusion per time stamp, optionally
//! tracked by one EIF per target (using the detections' RSSI readings).

use super::cameras::Cameras;
use super::detections::read_detections;
use super::ml::{Estimate, MlOptions, replay_ml};
use super::track::{RssiNodes, TrackOptions, track_with_rssi};
use anyhow::{Context, Result, bail, ensure};
use std::io::BufRead;
use std::path::PathBuf;

/// How estimates are made.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum FuseMethod {
    /// Paper 000's maximum-likelihood fusion: one estimate per person per `t`.
    #[default]
    Ml,
    /// ML estimates tracked by one EIF per target: adds a track id.
    Eif,
}

/// Where the cameras come from.
#[derive(Clone, Debug, PartialEq)]
pub enum CameraSource {
    /// A scenario (detections name cameras by node id).
    Scenario(PathBuf),
    /// An OpenCV calibration folder (`intrinsic/intr_<ID>.xml`, `extrinsic/extr_<ID>.xml`), with
    /// the image size for files that do not state it.
    OpenCv { dir: PathBuf, image_size: (u32, u32) },
}

/// What to fuse and how.
#[derive(Clone, Debug)]
pub struct FuseOptions {
    pub cameras: CameraSource,
    pub method: FuseMethod,
    /// Targets move on the plane z = H (m), e.g. 0 for people's foot points.
    pub plane_z: Option<f64>,
    /// Pixel noise of a detection (px).
    pub pixel_sigma: f64,
    /// Largest ground distance (m) between two cameras' views of one person.
    pub gate: f64,
    /// Report only people seen by at least this many cameras.
    pub min_cameras: usize,
}

impl FuseOptions {
    /// The command line's defaults with these cameras.
    pub fn new(cameras: CameraSource) -> FuseOptions {
        FuseOptions {
            cameras,
            method: FuseMethod::Ml,
            plane_z: None,
            pixel_sigma: 2.0,
            gate: 1.0,
            min_cameras: 1,
        }
    }
}

/// Load cameras and detections, fuse, and return the estimates.
///
/// # Errors
/// Unreadable or malformed cameras or detections, or invalid options.
pub fn fuse(opts: &FuseOptions, input: impl BufRead) -> Result<Vec<Estimate>> {
    ensure!(
        opts.pixel_sigma.is_finite() && opts.pixel_sigma > 0.0,
        "--pixel-sigma {} must be a positive number",
        opts.pixel_sigma
    );
    ensure!(
        opts.gate.is_finite() && opts.gate > 0.0,
        "--gate {} must be a positive number",
        opts.gate
    );
    if let Some(h) = opts.plane_z {
        ensure!(h.is_finite(), "--plane-z {h} must be finite");
    }
    let (cameras, motion, rssi_model) = match &opts.cameras {
        CameraSource::Scenario(path) => {
            let scenario = proto::scenario::Scenario::load(path)?;
            (
                Cameras::from_scenario(&scenario)?,
                scenario.method.motion,
                scenario.method.rssi_default,
            )
        }
        CameraSource::OpenCv { dir, image_size } => (
            Cameras::from_opencv_dir(dir, Some(*image_size))?,
            proto::models::MotionModel::default(),
            proto::models::RssiModel::default(),
        ),
    };
    let detections = read_detections(input).context("reading detections")?;
    if detections.is_empty() {
        bail!("no detections in the input");
    }
    let options = MlOptions {
        plane_z: opts.plane_z,
        pixel_sigma: opts.pixel_sigma,
        gate_m: opts.gate,
        min_cameras: opts.min_cameras,
        ..MlOptions::default()
    };
    let (estimates, skipped) = replay_ml(&detections, &cameras, &options);
    tracing::info!(
        detections = detections.len(),
        estimates = estimates.len(),
        skipped = ?skipped,
        "ML fusion done"
    );
    Ok(match opts.method {
        FuseMethod::Ml => estimates,
        FuseMethod::Eif => {
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
            tracing::info!(tracked = tracked.len(), counts = ?counts, "EIF tracking done");
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
