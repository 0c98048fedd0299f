//! External detections from any detector (JSON Lines) fused into estimates: cameras from a
//! scenario or an OpenCV calibration folder, paper 000's ML fusion per time stamp, optionally
//! tracked by one EIF per target (using the detections' RSSI readings).

use super::cameras::{Cameras, CamerasError};
use super::detections::{DetectionError, SkippedLines, read_detections};
use super::ml::{Estimate, MlOptions, Skipped, ViewNoise, replay_ml};
use super::track::{RssiNodes, TrackOptions, track_with_rssi};
use proto::scenario::ScenarioError;
use std::io::BufRead;
use std::path::PathBuf;
use thiserror::Error;

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
    /// With a plane: a view's ground error beyond its pixel noise.
    pub view_noise: ViewNoise,
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
            view_noise: ViewNoise::default(),
        }
    }
}

/// Why detections could not be fused.
#[derive(Debug, Error)]
pub enum FuseError {
    #[error("{0}")]
    Options(String),
    #[error(transparent)]
    Scenario(#[from] ScenarioError),
    #[error(transparent)]
    Cameras(#[from] CamerasError),
    #[error(transparent)]
    Read(#[from] DetectionError),
    #[error("no detection to fuse: the input is empty{0}")]
    Empty(String),
    #[error("no estimate from {detections} detection(s): {why}")]
    Nothing { detections: usize, why: String },
}

/// What a fusion made and what it could not use.
#[derive(Clone, Debug)]
pub struct Fused {
    pub estimates: Vec<Estimate>,
    /// Detections read (after skipped lines).
    pub detections: usize,
    pub skipped_lines: SkippedLines,
    /// Detections and groups the ML fusion could not use, by reason.
    pub skipped: Skipped,
}

/// Load cameras and detections, fuse, and return the estimates.
///
/// # Errors
/// As [`fuse_all`].
pub fn fuse(opts: &FuseOptions, input: impl BufRead) -> Result<Vec<Estimate>, FuseError> {
    Ok(fuse_all(opts, input)?.estimates)
}

fn check_options(opts: &FuseOptions) -> Result<(), FuseError> {
    let positive = |x: f64| x.is_finite() && x > 0.0;
    if !positive(opts.pixel_sigma) {
        return Err(FuseError::Options(format!(
            "--pixel-sigma {} must be a positive number",
            opts.pixel_sigma
        )));
    }
    if !positive(opts.gate) {
        return Err(FuseError::Options(format!(
            "--gate {} must be a positive number",
            opts.gate
        )));
    }
    if let Some(h) = opts.plane_z
        && !h.is_finite()
    {
        return Err(FuseError::Options(format!("--plane-z {h} must be finite")));
    }
    Ok(())
}

/// Why nothing came out, in words, with what would help.
fn why_nothing(opts: &FuseOptions, s: &Skipped, cameras: &Cameras) -> String {
    let mut why = Vec::new();
    if s.unknown_camera > 0 {
        let known: Vec<&str> = cameras.models.keys().map(String::as_str).take(8).collect();
        why.push(format!(
            "{} from cameras the calibration does not know (it knows {})",
            s.unknown_camera,
            known.join(", ")
        ));
    }
    if s.undistort_failed > 0 {
        why.push(format!(
            "{} whose pixel could not be undistorted",
            s.undistort_failed
        ));
    }
    if s.no_intersection > 0 {
        why.push(format!(
            "{} whose ray does not meet the plane z = {} in front of its camera",
            s.no_intersection,
            opts.plane_z.unwrap_or_default()
        ));
    }
    if s.ambiguous > 0 {
        why.push(format!(
            "{} at time stamps where one camera saw several people: without --plane-z only one person per time stamp can be placed; give --plane-z H (0 for foot points)",
            s.ambiguous
        ));
    }
    if s.too_few_cameras > 0 {
        why.push(format!(
            "{} group(s) seen by fewer than --min-cameras {} cameras",
            s.too_few_cameras, opts.min_cameras
        ));
    }
    if s.singular > 0 {
        why.push(format!("{} group(s) whose fusion was singular", s.singular));
    }
    if why.is_empty() {
        "nothing could be grouped".into()
    } else {
        why.join("; ")
    }
}

/// Load cameras and detections, fuse, and return the estimates with what was skipped. Lines
/// that are malformed or impossible are skipped (counted and named in [`Fused`]).
///
/// # Errors
/// Invalid options, unreadable or malformed cameras, unreadable input, an input without one
/// usable detection, or detections that give no estimate (the error says why).
pub fn fuse_all(opts: &FuseOptions, input: impl BufRead) -> Result<Fused, FuseError> {
    check_options(opts)?;
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
    let read = read_detections(input)?;
    if read.skipped.count > 0 {
        tracing::warn!("detections: {}", read.skipped);
    }
    let detections = read.detections;
    if detections.is_empty() {
        let skipped = if read.skipped.count > 0 {
            format!(" once bad lines are skipped ({})", read.skipped)
        } else {
            String::new()
        };
        return Err(FuseError::Empty(skipped));
    }
    let options = MlOptions {
        plane_z: opts.plane_z,
        pixel_sigma: opts.pixel_sigma,
        gate_m: opts.gate,
        min_cameras: opts.min_cameras,
        view_noise: opts.view_noise,
        ..MlOptions::default()
    };
    let (estimates, skipped) = replay_ml(&detections, &cameras, &options);
    tracing::info!(
        detections = detections.len(),
        estimates = estimates.len(),
        "ML fusion done"
    );
    if estimates.is_empty() {
        return Err(FuseError::Nothing {
            detections: detections.len(),
            why: why_nothing(opts, &skipped, &cameras),
        });
    }
    let estimates = match opts.method {
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
            tracing::info!(tracked = tracked.len(), "EIF tracking done");
            if counts.rssi_unknown_node > 0 {
                tracing::warn!(
                    readings = counts.rssi_unknown_node,
                    "RSSI readings from nodes that are not cameras of the fusion, not used"
                );
            }
            tracked
        }
    };
    Ok(Fused {
        estimates,
        detections: detections.len(),
        skipped_lines: read.skipped,
        skipped,
    })
}
