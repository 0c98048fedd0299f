//! Import of OpenCV `FileStorage` calibration files (XML), as in MultiviewX's `calibrations/`.

use crate::camera::{Distortion, Intrinsics, Pose};
use std::path::Path;
use thiserror::Error;

/// A calibration file that could not be used.
#[derive(Debug, Error)]
pub enum OpenCvError {
    #[error("cannot read {path}: {source}")]
    Io { path: String, source: std::io::Error },
    #[error("{path}: {problem}")]
    Format { path: String, problem: String },
}

/// Read an intrinsic file: camera matrix and distortion coefficients.
///
/// # Errors
/// Unreadable file, or a missing / malformed matrix, naming the file.
pub fn read_intrinsics(path: &Path) -> Result<(Intrinsics, Distortion), OpenCvError> {
    Err(OpenCvError::Format {
        path: path.display().to_string(),
        problem: "OpenCV import not implemented yet".into(),
    })
}

/// Read an extrinsic file: `rvec` and `tvec`, world → camera.
///
/// # Errors
/// Unreadable file, or a missing / malformed vector, naming the file.
pub fn read_extrinsics(path: &Path) -> Result<Pose, OpenCvError> {
    Err(OpenCvError::Format {
        path: path.display().to_string(),
        problem: "OpenCV import not implemented yet".into(),
    })
}
