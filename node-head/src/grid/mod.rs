//! Paper 001's grid-based recursive Bayesian estimator: a belief over the floor's cells,
//! predicted by a random walk and corrected by the product of the sensors' likelihoods
//! (eq. 12) — the optical one, which uses detections *and* non-detections, and the acoustic
//! one from ILD fingerprints.
//!
//! - [`layout`]: the cells, which are free, and which motion connects (walls respected);
//! - [`belief`]: prediction (eq. 3, 7) and correction (eq. 4–5, 8–9), mean, covariance,
//!   most likely cell, heat map;
//! - [`optical`]: each camera's probability of detection over the grid and its likelihood
//!   with and without a detection (eq. 2, 6);
//! - [`acoustic`]: the fingerprint likelihood of an ILD vector over the grid (eq. 16–18);
//! - [`rssi`]: a tag reading's likelihood through a node's RSSI model;
//! - [`report`]: the belief down-sampled for a `TrackReport`;
//! - [`locate`]: the estimator on the acoustic likelihood alone, frame by frame;
//! - [`bench`]: timing of the hot path.
//!
//! Everything here is sans-IO: time steps and observations are passed in.

pub mod acoustic;
pub mod belief;
pub mod bench;
mod convolve;
pub mod layout;
pub mod locate;
pub mod optical;
pub mod report;
pub mod rssi;

pub use belief::{Belief, Correction, Estimate, HeatMap, RandomWalk};
pub use layout::Grid;

use thiserror::Error;

/// Why the grid estimator refused an input; the refused input changed no state.
#[derive(Debug, Error)]
pub enum GridError {
    #[error("grid: {0}")]
    Invalid(String),
    #[error("camera {camera}: {problem}")]
    Camera { camera: u32, problem: String },
    #[error(transparent)]
    Acoustic(#[from] proto::acoustic::AcousticError),
}
