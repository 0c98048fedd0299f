//! One module per `ocelli` subcommand.

pub mod bench_transport;
pub mod peer;
pub mod scenario;
