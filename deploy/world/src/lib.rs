//! The simulated world: what is truly there, and what sensors would read of it.
//!
//! [`targets`] parses the scenario's targets and says where each truly is over time;
//! [`render`] draws what a camera sees (through its lens distortion, with noise and slowly
//! changing light); [`radio`] gives the RSSI a node reads of a tag; [`project`] makes
//! measurement-level detections (the truth projected plus pixel noise) for fast sweeps;
//! [`sources`] wraps them as the frame and radio sources a node process is given; [`prepare`]
//! fits a scenario's method to its simulated room before a run.
//!
//! Invariant: no node crate depends on this crate. Only the simulation runtime, the local
//! launcher (which injects these sources into real node processes) and the lab read it, so no
//! node can learn where a target truly is.

pub mod acoustics;
pub mod generate;
pub mod prepare;
pub mod project;
pub mod radio;
pub mod render;
pub mod sources;
pub mod targets;

pub use prepare::prepare;
pub use targets::{Pause, Target, Trajectory, set_targets, targets};
