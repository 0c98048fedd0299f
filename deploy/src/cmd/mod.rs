//! One module per `ocelli` subcommand.

pub mod bench_head;
pub mod scenario;
