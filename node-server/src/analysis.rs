//! Reading a recording back for analysis: load it with its scenario, and feed its inputs through
//! a fresh [`ServerNode`] so that every track report can be seen with the global id and owner
//! the server gave it at that moment.

use crate::core::{ServerConfig, ServerNode};
use crate::record::{Record, Stamped};
use crate::recording::{RecordingError, Skipped, read_all};
use proto::NodeId;
use proto::scenario::{Scenario, ScenarioError};
use std::path::Path;
use thiserror::Error;

/// A recording that cannot be analysed.
#[derive(Debug, Error)]
pub enum LoadError {
    #[error(transparent)]
    Recording(#[from] RecordingError),
    #[error("recorded scenario: {0}")]
    Scenario(#[from] ScenarioError),
    #[error("recording {0} holds no scenario; pass one")]
    NoScenario(String),
}

/// A recording in memory with the scenario it ran.
#[derive(Debug)]
pub struct Loaded {
    pub scenario: Scenario,
    pub records: Vec<Stamped>,
    /// Damaged stretches of the recording that reading skipped, in file order (empty for
    /// records that did not come from a file).
    pub skipped: Vec<Skipped>,
}

impl Loaded {
    /// The run's time origin and whether it has truth, if the recording says (the first
    /// [`Record::Origin`]; recordings made before it existed say nothing).
    pub fn origin(&self) -> Option<crate::Origin> {
        self.records.iter().find_map(|s| match s.record {
            Record::Origin(o) => Some(o),
            _ => None,
        })
    }

    /// The server's node id: the scenario's server, else the source of its sent frames.
    pub fn server_id(&self) -> NodeId {
        self.scenario
            .server()
            .map(|n| NodeId(n.id))
            .or_else(|| {
                self.records.iter().find_map(|s| match &s.record {
                    Record::Sent { env, .. } => Some(env.source),
                    _ => None,
                })
            })
            .unwrap_or(NodeId(0))
    }
}

/// Load a recording; `scenario` overrides the one recorded in it. Damaged stretches are
/// skipped and listed in [`Loaded::skipped`].
///
/// # Errors
/// An unreadable recording, a recorded scenario that does not parse, or no scenario at all.
pub fn load(path: &Path, scenario: Option<Scenario>) -> Result<Loaded, LoadError> {
    let back = read_all(path)?;
    let scenario = match scenario {
        Some(s) => s,
        None => {
            let toml = back
                .records
                .iter()
                .find_map(|s| match &s.record {
                    Record::Scenario(t) => Some(t.clone()),
                    _ => None,
                })
                .ok_or_else(|| LoadError::NoScenario(path.display().to_string()))?;
            Scenario::from_toml(&toml, &format!("{} (recorded)", path.display()))?
        }
    };
    Ok(Loaded {
        scenario,
        records: back.records,
        skipped: back.skipped,
    })
}

/// Feed the recording's received envelopes, ticks and restarts through a fresh server and call
/// `visit` after each record with the server's state at that point.
pub fn rebuild(loaded: &Loaded, mut visit: impl FnMut(&ServerNode, &Stamped)) {
    let mut cfg = ServerConfig::from_scenario(loaded.scenario.clone(), loaded.server_id());
    cfg.journal = false;
    let mut node = ServerNode::new(cfg);
    for s in &loaded.records {
        node.feed(s);
        visit(&node, s);
    }
}

/// The camera measurements a logging run recorded, in recording order, each with the server
/// time it was recorded at.
pub fn measured_frames(loaded: &Loaded) -> impl Iterator<Item = (proto::ClusterTime, &crate::MeasuredFrame)> {
    loaded.records.iter().filter_map(|s| match &s.record {
        Record::Measured(m) => Some((s.at, m)),
        _ => None,
    })
}
