//! One module per `ocelli` subcommand.

pub mod scenario;
pub mod undistort;
