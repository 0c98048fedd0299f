//! The Ocelli server: the one place that sees the whole network (paper 004 §3.3, paper 002 §II).
//!
//! A sans-IO core ([`ServerNode`]) keeps membership and liveness, assigns cameras and targets to
//! heads, hands tracks over between clusters and away from dead heads, keeps one global id per
//! physical target, and leads time sync. Everything it sees and decides goes to a crash-safe
//! [`recording`], from which [`export`] and [`report`] are computed and from which a restarted
//! server resumes.

pub mod analysis;
pub mod core;
#[cfg(test)]
mod core_tests;
pub mod decision;
pub mod export;
#[cfg(test)]
mod failover_tests;
pub mod membership;
pub mod metrics;
pub mod process;
pub mod record;
pub mod recording;
pub mod report;
#[cfg(test)]
mod report_tests;
pub mod tag_homes;
pub mod tail;
#[cfg(test)]
pub(crate) mod testkit;
pub mod tracks;

pub use core::{Counters, RestoreStats, ServerConfig, ServerNode};
pub use decision::{Decision, HandoverReason};
pub use record::{MeasuredDetection, MeasuredFrame, Origin, Record, Stamped};
pub use recording::{Reader, Recorder, RecordingError};
