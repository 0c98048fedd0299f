//! Identifiers of nodes and targets, and the roles nodes play.

use serde::{Deserialize, Serialize};
use std::fmt;

/// A node's id, unique within a deployment (cameras, heads and the server share one space).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord, Serialize, Deserialize)]
pub struct NodeId(pub u32);

/// A target (track) id. Heads allocate local ids; the server hands out global ones.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord, Serialize, Deserialize)]
pub struct TargetId(pub u32);

impl fmt::Display for NodeId {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "n{}", self.0)
    }
}

impl fmt::Display for TargetId {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "t{}", self.0)
    }
}

/// The role a process plays. Order is part of the wire format.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, Serialize, Deserialize)]
pub enum Role {
    Camera,
    Head,
    Server,
    /// Benchmarks, probes and other tools that speak the protocol.
    Tool,
}

impl fmt::Display for Role {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(match self {
            Role::Camera => "camera",
            Role::Head => "head",
            Role::Server => "server",
            Role::Tool => "tool",
        })
    }
}
