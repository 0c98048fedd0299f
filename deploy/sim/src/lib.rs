//! The simulation runtime: every node core of a scenario in one process, on a virtual clock,
//! talking through a simulated network ([`net`]: latency, jitter, loss, partitions, clock
//! skew), sensing the simulated world (crate `world`), deterministic for a seed. [`runtime`]
//! drives the cores through `proto::node::Node` as the process runtime does; [`camera`]
//! senses for each camera; [`acoustic`] listens for each acoustic node and surveys the room's
//! fingerprints; [`faults`] injects sensor faults into the world; [`logged`] feeds
//! a logging run's recording back instead of sensing; [`truth`] scores a run against the world.

pub mod acoustic;
mod camera;
pub mod faults;
pub mod logged;
pub mod net;
pub mod queue;
pub mod recorded_truth;
pub mod runtime;
pub mod truth;

pub use recorded_truth::RecordedTruth;
pub use runtime::{Level, NetCounters, Sim, SimOptions, SimOutcome};
pub use truth::WorldTruth;

use proto::NodeId;
use proto::scenario::ScenarioError;
use thiserror::Error;

/// A simulation that cannot be built.
#[derive(Debug, Error)]
pub enum SimError {
    #[error(transparent)]
    Scenario(#[from] ScenarioError),
    #[error("node {node}: {problem}")]
    Node { node: NodeId, problem: String },
}
