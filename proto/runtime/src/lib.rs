//! `runtime` runs Ocelli node cores as OS processes: [`process::run`] drives any
//! `proto::node::Node` over one of the [`transport`]s (iceoryx2 shared memory on one host, TCP
//! between hosts, in-process channels in tests), with the cluster [`clock`] every process
//! keeps and the transport [`config`] every role builds the same way from the scenario.
//!
//! The vocabulary (messages, wire encoding, models) is `proto`'s; a crate that needs only the
//! vocabulary depends on `proto` and builds neither tokio nor iceoryx2.

pub mod clock;
pub mod config;
pub mod process;
pub mod transport;

pub use clock::HostClock;
pub use process::{Hooks, NoHooks, ProcessConfig, RunError, RunSummary, UndeliveredAt, run};
