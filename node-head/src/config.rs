//! What a head needs to know, built from the scenario: its id, the server, the method, and a
//! table of every camera node it may be given (camera model, position, power figures, cost
//! factor), with the ones the scenario assigns to it marked as members.

use crate::fusion::ml::DepthHandling;
use nalgebra::Vector3;
use proto::NodeId;
use proto::camera::CameraModel;
use proto::scenario::{Method, NodeRole, PowerFigures, Scenario, ScenarioError, Wall};
use thiserror::Error;

/// A head that cannot be configured.
#[derive(Debug, Error)]
pub enum ConfigError {
    #[error("node {0} is not a head in the scenario")]
    NotAHead(u32),
    #[error(transparent)]
    Scenario(#[from] ScenarioError),
}

/// One camera node as the head sees it.
#[derive(Clone, Debug, PartialEq)]
pub struct NodeInfo {
    pub id: NodeId,
    pub camera: CameraModel,
    /// Where the node's radio sits (its `position`, else the camera centre), world frame:
    /// where RSSI distances are measured from.
    pub position: Vector3<f64>,
    pub rssi: bool,
    pub power: PowerFigures,
    pub cost_factor: f64,
    /// Frames per second: the time between p_{i,t−1} and p_{i,t}.
    pub fps: f64,
    /// In this head's cluster at start.
    pub member: bool,
    /// A radio-only node: `camera` is a blind placeholder at `position`; it is never Active
    /// (CameraOff is its working mode) and only its RSSI is weighed.
    pub radio_only: bool,
}

impl NodeInfo {
    /// The mode the node is put in when `mode` is asked for: a radio-only node has no camera,
    /// so Active is CameraOff for it.
    pub fn working_mode(&self, mode: proto::Mode) -> proto::Mode {
        if self.radio_only && mode == proto::Mode::Active {
            proto::Mode::CameraOff
        } else {
            mode
        }
    }
}

/// Everything the core needs.
#[derive(Clone, Debug, PartialEq)]
pub struct HeadConfig {
    pub id: NodeId,
    pub server: Option<NodeId>,
    pub method: Method,
    pub nodes: Vec<NodeInfo>,
    /// World box, for rejecting ghost births.
    pub bounds: ([f64; 3], [f64; 3]),
    /// The world's occluding walls: activation expects no camera measurement through them.
    pub walls: Vec<Wall>,
    /// Fewest cameras that must agree to start a track (1 allows a wide single-camera prior).
    pub birth_min_cameras: usize,
    /// Height assumed for single-camera priors and for ML's known plane, metres.
    pub target_plane_z: f64,
    /// How ML gets depth.
    pub ml_depth: DepthHandling,
}

impl HeadConfig {
    /// The head `id` of `scenario`.
    ///
    /// # Errors
    /// `id` is not a head, or a camera's geometry cannot be built.
    pub fn from_scenario(scenario: &Scenario, id: u32) -> Result<Self, ConfigError> {
        match scenario.node(id) {
            Some(n) if n.role == NodeRole::Head => {}
            _ => return Err(ConfigError::NotAHead(id)),
        }
        let clusters = scenario.clusters();
        let members = clusters.get(&NodeId(id)).cloned().unwrap_or_default();
        let mut nodes = Vec::new();
        for spec in scenario.cameras() {
            let camera = scenario.camera_or_blind(spec.id)?;
            nodes.push(NodeInfo {
                id: NodeId(spec.id),
                position: scenario.sensor_position(spec.id)?,
                camera,
                radio_only: spec.radio_only(),
                rssi: spec.rssi,
                power: scenario.power_of(spec.id),
                cost_factor: spec.cost_factor,
                fps: spec.camera.as_ref().map_or(5.0, |c| c.fps),
                member: members.contains(&NodeId(spec.id)),
            });
        }
        let target_plane_z = scenario.method.target_plane_z();
        let member_count = nodes.iter().filter(|n| n.member).count();
        Ok(HeadConfig {
            id: NodeId(id),
            server: scenario.server().map(|s| NodeId(s.id)),
            method: scenario.method.clone(),
            nodes,
            bounds: (scenario.world.min, scenario.world.max),
            walls: scenario.world.walls.clone(),
            birth_min_cameras: if member_count <= 1 { 1 } else { 2 },
            target_plane_z,
            ml_depth: DepthHandling::KnownPlane {
                z: target_plane_z,
                sigma: 0.05,
            },
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn default_scenario_heads_have_their_clusters() {
        let s = Scenario::default_scenario();
        let c = HeadConfig::from_scenario(&s, 2).unwrap();
        assert_eq!(c.server, Some(NodeId(1)));
        assert_eq!(c.nodes.len(), s.cameras().count());
        let members: Vec<_> = c.nodes.iter().filter(|n| n.member).map(|n| n.id).collect();
        assert_eq!(members, s.clusters()[&NodeId(2)]);
        assert!(matches!(
            HeadConfig::from_scenario(&s, 10),
            Err(ConfigError::NotAHead(10))
        ));
    }
}
