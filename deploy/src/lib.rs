//! Putting Ocelli nodes together: the `ocelli` command line.
pub mod cli;
pub mod cmd;
pub mod deploy;
pub mod launch;
pub mod supervisor;
