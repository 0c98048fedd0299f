//! What one acoustic node needs to know, built from the scenario and its node id.

use proto::NodeId;
use proto::acoustic::IldSettings;
use proto::scenario::{NodeRole, Scenario};
use thiserror::Error;

/// An acoustic configuration that could not be built.
#[derive(Debug, Error)]
pub enum ConfigError {
    #[error("node {0} is not an acoustic node in the scenario")]
    NotAcoustic(u32),
}

/// Everything the acoustic core needs.
#[derive(Clone, Debug, PartialEq)]
pub struct AcousticConfig {
    pub id: NodeId,
    /// The head it sends ILD vectors to (an `Assignment` can change it).
    pub head: Option<NodeId>,
    pub server: Option<NodeId>,
    /// How a frame becomes an ILD vector.
    pub ild: IldSettings,
    /// Audio per ILD vector, ms.
    pub frame_ms: f64,
    /// How often a `NodeStatus` goes to the head and the server, ms.
    pub status_period_ms: u64,
    /// Frames stamped farther than this from now are refused, ms.
    pub max_age_ms: u64,
}

impl AcousticConfig {
    /// The configuration of acoustic node `id` in `scenario`.
    ///
    /// # Errors
    /// The node does not exist or is not an acoustic node.
    pub fn from_scenario(scenario: &Scenario, id: u32) -> Result<AcousticConfig, ConfigError> {
        let node = scenario
            .node(id)
            .filter(|n| n.role == NodeRole::Acoustic)
            .ok_or(ConfigError::NotAcoustic(id))?;
        let spec = node.acoustic.clone().ok_or(ConfigError::NotAcoustic(id))?;
        Ok(AcousticConfig {
            id: NodeId(id),
            head: scenario.head_of(id).map(NodeId),
            server: scenario.server().map(|s| NodeId(s.id)),
            ild: spec.ild,
            frame_ms: spec.frame_ms,
            status_period_ms: 1000,
            max_age_ms: scenario
                .method
                .capture_max_age_ms()
                .max(2 * spec.frame_ms.ceil() as u64),
        })
    }

    /// Samples per channel of one frame.
    pub fn frame_samples(&self) -> usize {
        (self.frame_ms / 1000.0 * f64::from(self.ild.sample_rate)).round() as usize
    }
}
