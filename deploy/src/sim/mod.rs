//! The simulation runtime: every node's state machine in one process, a virtual clock and a
//! simulated network, deterministic for a seed.

pub mod faults;
pub mod logged;
pub mod net;
pub mod queue;
pub mod runtime;
