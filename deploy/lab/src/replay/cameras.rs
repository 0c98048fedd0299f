//! The cameras a replay projects through: from a scenario (named by node id, `"12"`) or from an
//! OpenCV calibration folder (named by file, `Camera1`). A left-handed calibration (MultiviewX)
//! is mirrored on import ([`proto::opencv`]); [`Cameras`] remembers the reflection so that every
//! estimate is reported back in the calibration's own world coordinates.

use nalgebra::{Matrix3, Vector3};
use proto::camera::CameraModel;
use proto::opencv::{ImportOptions, MirrorAxis};
use proto::scenario::Scenario;
use std::collections::BTreeMap;
use std::path::Path;
use thiserror::Error;

/// Cameras by id, and the reflection between the solver's world and the user's.
#[derive(Clone, Debug)]
pub struct Cameras {
    pub models: BTreeMap<String, CameraModel>,
    /// `Some(axis)` when every camera was mirrored on import: the solver works in `S·X`.
    pub mirror: Option<MirrorAxis>,
}

#[derive(Debug, Error)]
pub enum CamerasError {
    #[error(transparent)]
    OpenCv(#[from] proto::opencv::OpenCvError),
    #[error(transparent)]
    Scenario(#[from] proto::scenario::ScenarioError),
    #[error("{dir}: cameras {mirrored:?} are left-handed and the others are not; one world cannot hold both")]
    MixedHandedness { dir: String, mirrored: Vec<String> },
    #[error("the scenario has no camera nodes")]
    NoCameras,
}

impl Cameras {
    /// Every camera node of a scenario, keyed by its node id.
    ///
    /// # Errors
    /// A camera node whose model cannot be built, or no camera at all.
    pub fn from_scenario(scenario: &Scenario) -> Result<Cameras, CamerasError> {
        let mut models = BTreeMap::new();
        for node in scenario.cameras() {
            models.insert(node.id.to_string(), scenario.camera_model(node.id)?);
        }
        if models.is_empty() {
            return Err(CamerasError::NoCameras);
        }
        Ok(Cameras { models, mirror: None })
    }

    /// A calibration folder laid out as MultiviewX's (`intrinsic/intr_<ID>.xml`,
    /// `extrinsic/extr_<ID>.xml`). Left-handed cameras are mirrored across y (the world stays
    /// z-up, so a plane z = H keeps its meaning); estimates are mirrored back on output.
    ///
    /// # Errors
    /// Unreadable or malformed files, or a folder mixing left- and right-handed cameras.
    pub fn from_opencv_dir(dir: &Path, image_size: Option<(u32, u32)>) -> Result<Cameras, CamerasError> {
        let options = ImportOptions {
            mirror_axis: MirrorAxis::Y,
            image_size,
            ..ImportOptions::default()
        };
        let imported = proto::opencv::read_calibration_dir_with(dir, &options)?;
        let mirrored: Vec<String> = imported
            .iter()
            .filter(|(_, c)| c.mirrored)
            .map(|(id, _)| id.clone())
            .collect();
        let mirror = match mirrored.len() {
            0 => None,
            n if n == imported.len() => Some(MirrorAxis::Y),
            _ => {
                return Err(CamerasError::MixedHandedness {
                    dir: dir.display().to_string(),
                    mirrored,
                });
            }
        };
        Ok(Cameras {
            models: imported.into_iter().map(|(id, c)| (id, c.model)).collect(),
            mirror,
        })
    }

    /// A point of the user's world in the solver's world (and back: `S` is its own inverse).
    pub fn to_solver(&self, p: &Vector3<f64>) -> Vector3<f64> {
        self.mirror.map_or(*p, |axis| axis.apply(p))
    }

    /// A solver-world point in the user's world.
    pub fn to_user(&self, p: &Vector3<f64>) -> Vector3<f64> {
        self.to_solver(p)
    }

    /// A solver-world covariance in the user's world, `S Σ S`.
    pub fn cov_to_user(&self, c: &Matrix3<f64>) -> Matrix3<f64> {
        match self.mirror {
            None => *c,
            Some(axis) => {
                let s = Matrix3::from_diagonal(&axis.diagonal());
                s * c * s
            }
        }
    }
}
