//! What one camera node needs to know, built from the scenario and its node id.

use crate::segment::SegmentParams;
use proto::NodeId;
use proto::camera::CameraModel;
use proto::msg::Mode;
use proto::scenario::particle::ParticleParams;
use proto::scenario::{CameraTracker, Fusion, NodeRole, Scenario, ScenarioError};
use proto::sensor::ReferencePoint;
use thiserror::Error;

/// A camera configuration that could not be built.
#[derive(Debug, Error)]
pub enum ConfigError {
    #[error(transparent)]
    Scenario(#[from] ScenarioError),
    #[error("node {0} is not a camera node in the scenario")]
    NotACamera(u32),
}

/// Everything the camera core needs.
#[derive(Clone, Debug)]
pub struct CameraConfig {
    pub id: NodeId,
    /// The cluster head it reports to (an `Assignment` can change it).
    pub head: Option<NodeId>,
    pub server: Option<NodeId>,
    pub camera: CameraModel,
    pub fusion: Fusion,
    pub segment: SegmentParams,
    /// Segmentation noise, pixels (paper 002: 18).
    pub pixel_sigma: f64,
    /// χ² (2 dof) gate for associating detections with priors.
    pub gate_chi2: f64,
    pub reference: ReferencePoint,
    /// How often a `NodeStatus` goes to the head and the server.
    pub status_period_ms: u64,
    /// Priors older than this are forgotten.
    pub prior_timeout_ms: u64,
    /// Detections and RSSI readings older than this are not used.
    pub max_age_ms: u64,
    /// The heads' filter step (`[method] step-ms`): ground-plane people go out at most once
    /// per step.
    pub step_ms: u64,
    /// Whether this node measures RSSI.
    pub rssi: bool,
    /// Include the previous frame's point in centralized measurements (paper 000 eq. 13).
    pub previous_point: bool,
    pub initial_mode: Mode,
    pub fps: f64,
    /// A logging run: measure every frame whatever the mode and send its measurements to the
    /// server's recording ([`crate::record_all`]).
    pub record_all: bool,
    /// What the camera makes of its frames: pin-hole points of segmented regions, or paper
    /// 004's per-person particle filters sending ground-plane people
    /// ([`crate::ground_people`]).
    pub tracker: CameraTracker,
    /// The particle filters' parameters (`[method.particle]`).
    pub particle: ParticleParams,
    /// A radio-only node (no camera geometry in the scenario): `camera` is a blind placeholder
    /// at the radio's place, it gets no frames and starts in CameraOff, its working mode.
    pub radio_only: bool,
}

impl CameraConfig {
    /// The configuration of camera node `id` in `scenario`.
    ///
    /// # Errors
    /// The node does not exist, is not a camera, or its geometry cannot be built.
    pub fn from_scenario(scenario: &Scenario, id: u32) -> Result<CameraConfig, ConfigError> {
        let node = scenario
            .node(id)
            .filter(|n| n.role == NodeRole::Camera)
            .ok_or(ConfigError::NotACamera(id))?;
        let camera = scenario.camera_or_blind(id)?;
        let radio_only = node.radio_only();
        let head = node.head.or_else(|| scenario.heads().next().map(|h| h.id));
        let m = &scenario.method;
        let fps = node.camera.as_ref().map_or(5.0, |c| c.fps);
        let mut segment = SegmentParams::for_scenario(scenario, camera.intrinsics.width);
        segment.adaptive_background = segment.adaptive_background.scaled_to_fps(fps);
        Ok(CameraConfig {
            id: NodeId(id),
            head: head.map(NodeId),
            server: scenario.server().map(|s| NodeId(s.id)),
            segment,
            camera,
            fusion: m.fusion,
            pixel_sigma: m.pixel_sigma,
            gate_chi2: m.gate_chi2,
            reference: ReferencePoint::Centre,
            status_period_ms: 1000,
            prior_timeout_ms: m.track_timeout_ms,
            max_age_ms: m.capture_max_age_ms(),
            step_ms: m.step_ms,
            rssi: node.rssi,
            previous_point: m.previous_point,
            initial_mode: if radio_only { Mode::CameraOff } else { Mode::Active },
            fps,
            record_all: false,
            tracker: m.camera_tracker,
            particle: m.particle.clone(),
            radio_only,
        })
    }
}
