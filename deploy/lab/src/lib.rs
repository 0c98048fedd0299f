//! The lab: what measures and studies Ocelli rather than runs it. [`experiment`] reproduces the
//! papers' experiments in the simulation with our tables beside the papers'; [`replay`]
//! re-runs a logging run's recording through the heads with another method and policy, and
//! fuses external detections from any detector; [`report`] scores a recording by one rule;
//! [`bench`] times the hot paths.

pub mod bench;
mod error;
pub mod experiment;
pub mod progress;
pub mod replay;
pub mod report;
pub mod skipped;

pub use error::{LabError, Result};
