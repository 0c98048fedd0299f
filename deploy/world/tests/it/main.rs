//! The simulated world's integration tests: its targets against the scenario files, and its
//! rendered frames through the camera's real segmentation pipelines. One binary (matklad,
//! "Delete Cargo Integration Tests").

mod pipelines;
mod targets;
