//! One module per `ocelli` subcommand.

pub mod bench_camera;
pub mod scenario;
