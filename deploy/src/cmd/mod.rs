//! One module per `ocelli` subcommand.

pub mod export;
pub mod report;
pub mod bench_head;
pub mod bench_camera;
pub mod scenario;
pub mod undistort;
