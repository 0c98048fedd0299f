//! The scenario file: one TOML document describes a deployment — the world, every node, the
//! method parameters and, for simulation, the targets. `launch`, `sim`, `experiment` and a Pi
//! deployment all read it.
//!
//! Typed serde structs with `deny_unknown_fields` and kebab-case keys; [`Scenario::from_toml`]
//! reports the path, the field and what was expected, then [`Scenario::validate`] checks what
//! types cannot (unique ids, cameras that name an existing head, finite geometry).

use crate::camera::{CameraModel, Distortion, Intrinsics, Pose};
use crate::ids::NodeId;
use crate::models::{MotionModel, RssiModel};
use nalgebra::Vector3;
use serde::{Deserialize, Serialize};
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use thiserror::Error;

mod acoustic_spec;
mod check;
mod radio_source;

pub use radio_source::{RadioSpec, blind_camera};
pub mod particle;

pub use particle::ParticleParams;

/// The embedded default scenario, modelled on paper 002's 21-camera testbed.
pub const DEFAULT_SCENARIO_TOML: &str = include_str!("../scenarios/default.toml");

/// A whole deployment.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, rename_all = "kebab-case")]
pub struct Scenario {
    pub name: String,
    #[serde(default)]
    pub description: String,
    pub world: World,
    #[serde(default)]
    pub network: Network,
    #[serde(default)]
    pub method: Method,
    #[serde(default)]
    pub power: PowerFigures,
    pub nodes: Vec<NodeSpec>,
    /// The simulated world's targets (trajectory, size, colour, tag), opaque here: only the
    /// simulation reads them (crate `world`), so no node can see where a target truly is.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub targets: Vec<toml::Table>,
}

/// The room and what occludes inside it.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, rename_all = "kebab-case")]
pub struct World {
    /// Room bounds `[x, y, z]` min and max, metres; z = 0 is the floor.
    pub min: [f64; 3],
    pub max: [f64; 3],
    #[serde(default)]
    pub walls: Vec<Wall>,
    /// RSSI propagation of the simulated world (ignored by real deployments).
    #[serde(default)]
    pub radio: RadioWorld,
    /// Where the world is on Earth (Google Earth, Foxglove's location fixes), if known.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub geo: Option<crate::geo::Geo>,
}

/// A vertical wall segment from floor to `height` that occludes cameras and attenuates radio.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, rename_all = "kebab-case")]
pub struct Wall {
    pub from: [f64; 2],
    pub to: [f64; 2],
    pub height: f64,
    #[serde(default = "default_wall_attenuation")]
    pub attenuation_db: f64,
}

fn default_wall_attenuation() -> f64 {
    6.0
}

impl Wall {
    /// Whether the straight segment `a → b` passes through this wall below its top.
    pub fn crosses(&self, a: &Vector3<f64>, b: &Vector3<f64>) -> bool {
        let (px, py) = (self.from[0], self.from[1]);
        let (ex, ey) = (self.to[0] - px, self.to[1] - py);
        let (dx, dy) = (b.x - a.x, b.y - a.y);
        let denom = dx * ey - dy * ex;
        if denom.abs() < 1e-12 {
            return false;
        }
        let (apx, apy) = (px - a.x, py - a.y);
        let s = (apx * ey - apy * ex) / denom;
        let u = (apx * dy - apy * dx) / denom;
        let z = a.z + (b.z - a.z) * s;
        (0.0..=1.0).contains(&s) && (0.0..=1.0).contains(&u) && z <= self.height
    }
}

impl World {
    /// Whether a wall hides `b` from `a` (line of sight crosses a wall below its top).
    pub fn occluded(&self, a: &Vector3<f64>, b: &Vector3<f64>) -> bool {
        self.walls.iter().any(|w| w.crosses(a, b))
    }
}

/// How the simulated world treats radio: log-distance path loss plus a location-dependent
/// multipath field, a constant offset per node, wall attenuation and noise.
///
/// The defaults are ours. Real BLE data (`ocelli experiment ble-rssi`, twelve sensors in one
/// room) has a weaker smooth field (2.7 dB over about 1.2 m), more per-reading noise (4.6 dB)
/// and a 2.8 dB constant offset per sensor: `docs/results.md` compares them.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, rename_all = "kebab-case")]
pub struct RadioWorld {
    /// Received power at 1 m, dBm.
    pub tx_power_dbm: f64,
    /// Path-loss exponent n in `−10 n log10 d`.
    pub path_loss_exponent: f64,
    /// Standard deviation of the smooth multipath field, dB.
    pub multipath_db: f64,
    /// Spatial correlation length of the multipath field, metres.
    pub multipath_length_m: f64,
    /// Per-reading noise, dB.
    pub noise_db: f64,
    /// Standard deviation of each node's constant offset (antenna, housing, mounting), dB.
    #[serde(default)]
    pub node_offset_db: f64,
}

impl Default for RadioWorld {
    fn default() -> Self {
        RadioWorld {
            tx_power_dbm: -48.0,
            path_loss_exponent: 2.6,
            multipath_db: 5.0,
            multipath_length_m: 1.5,
            noise_db: 2.0,
            node_offset_db: 0.0,
        }
    }
}

/// Which runtime transport nodes use.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum TransportKind {
    /// iceoryx2 shared memory, same host.
    #[default]
    Ipc,
    /// tokio TCP, between hosts.
    Tcp,
}

/// Network parameters shared by every node.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, rename_all = "kebab-case")]
pub struct Network {
    pub transport: TransportKind,
    /// iceoryx2 service-name prefix, so parallel clusters and tests never collide.
    pub domain: String,
    pub heartbeat_ms: u64,
    /// A peer silent for this long is considered down.
    pub liveness_timeout_ms: u64,
    pub sync_beacon_ms: u64,
    /// Outgoing queue length per link; droppable messages beyond it are dropped and counted.
    pub queue_len: usize,
    /// TCP without TLS: anyone who reaches a node's port can pose as any node. For closed
    /// test networks only; every node logs it loudly.
    #[serde(default)]
    pub insecure: bool,
}

impl Default for Network {
    fn default() -> Self {
        Network {
            transport: TransportKind::Ipc,
            domain: "ocelli".into(),
            heartbeat_ms: 200,
            liveness_timeout_ms: 1000,
            sync_beacon_ms: 1000,
            queue_len: 256,
            insecure: false,
        }
    }
}

/// How measurements are fused.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum Fusion {
    /// Nodes send Ω_i, ξ_i; the head sums (paper 002 §III).
    #[default]
    DistributedEif,
    /// Nodes send undistorted measurements; the head linearizes (paper 000).
    CentralizedEif,
    /// Maximum likelihood per step (paper 000 §3).
    Ml,
    /// Paper 001's grid-based recursive Bayesian estimator: cameras' detections *and*
    /// non-detections, acoustic nodes' ILD fingerprints and tag RSSI as likelihoods over a grid
    /// of the floor (`[method.grid]`).
    Grid,
}

impl Fusion {
    /// The scenario file's spelling (`distributed-eif`, …), for messages.
    pub fn name(self) -> &'static str {
        match self {
            Fusion::DistributedEif => "distributed-eif",
            Fusion::CentralizedEif => "centralized-eif",
            Fusion::Ml => "ml",
            Fusion::Grid => "grid",
        }
    }

    /// Whether nodes answer the head's priors with their information contribution Ω_i, ξ_i
    /// (otherwise they send measurements and the head models them).
    pub fn distributed(self) -> bool {
        self == Fusion::DistributedEif
    }
}

/// Which sensors the head keeps on.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum Activation {
    /// Every camera on (paper 002 Method1).
    AllOn,
    /// Camera-only entropy selection (Method2, paper 000 §5).
    CameraEntropy,
    /// RSSI training plus full-node Active/Inactive activation (Method3).
    FullNode,
    /// Active / CameraOff / Inactive (paper 002's proposed method).
    #[default]
    ThreeMode,
}

impl Activation {
    /// The scenario file's spelling (`three-mode`, …), for messages.
    pub fn name(self) -> &'static str {
        match self {
            Activation::AllOn => "all-on",
            Activation::CameraEntropy => "camera-entropy",
            Activation::FullNode => "full-node",
            Activation::ThreeMode => "three-mode",
        }
    }
}

/// Which segmentation pipeline cameras run.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum Segmentation {
    /// Reference-image difference + HSI colour (paper 000 §6.1.1). Older files call it
    /// `paper000`.
    #[serde(alias = "paper000")]
    ColourDifference,
    /// Adaptive per-pixel background with confidence (paper 004 §3.2.1). Older files call it
    /// `paper004`.
    #[default]
    #[serde(alias = "paper004")]
    AdaptiveBackground,
}

/// What a camera makes of its frames.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum CameraTracker {
    /// Segmented regions, each sent as a pin-hole point (papers 000 and 002).
    #[default]
    Segmentation,
    /// One colour particle filter per person on the adaptive background's regions, each
    /// person sent as a ground-plane position with size and colour histogram (paper 004 §2,
    /// §3.2). Needs frames: the measurement-level simulation has none, and converts its
    /// projected boxes to the ground plane instead.
    Particle,
}

/// Method parameters.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, rename_all = "kebab-case")]
pub struct Method {
    pub fusion: Fusion,
    pub activation: Activation,
    pub segmentation: Segmentation,
    /// Filter step period, ms.
    pub step_ms: u64,
    /// How long after the prior a head waits for contributions, ms.
    pub deadline_ms: u64,
    /// Segmentation noise, pixels (18 in paper 002).
    pub pixel_sigma: f64,
    pub motion: MotionModel,
    /// The default RSSI model (paper 002 eq. 2).
    pub rssi_default: RssiModel,
    /// Replace `rssi-default` before a simulated run by the model fitted to the nodes' readings
    /// of each other in the simulated room, as paper 002 §VI fitted its default model to its
    /// testbed (`ocelli scenario survey` prints that fit).
    #[serde(default)]
    pub rssi_survey: bool,
    /// Training window M of Algorithm 1.
    pub rssi_window: usize,
    /// Guard for 1/a → ε in Algorithm 1.
    pub rssi_epsilon: f64,
    /// Weight of energy against information in the activation reward: nats per mJ of energy
    /// (a power difference in mW held for one step of `step_ms`).
    pub energy_weight: f64,
    /// Include p_{i,t−1} in centralized measurements (paper 000 eq. 13).
    pub previous_point: bool,
    /// Drop a track after this long without measurements, ms.
    pub track_timeout_ms: u64,
    /// Mahalanobis gate (χ², 2 dof) for associating detections with tracks.
    pub gate_chi2: f64,
    /// Activation drops lost cameras: a camera that is on and expected to see a track but
    /// delivered nothing last step is not counted among the sensors in use, nor switched, until
    /// it delivers again (paper 000 §6.2's lost measurements). Off (the default): every camera
    /// on counts as its mode says.
    #[serde(default)]
    pub drop_lost_cameras: bool,
    /// Track tags no camera sees by their radio alone (`node_head::unseen`): a cluster with
    /// cameras keeps a radio search track while it holds none (so its nodes report the tags
    /// they hear), wakes its radios for a tag no track claims, and gives such a tag a radio
    /// track at its RSSI fix. Off (the default): in the simulated rooms an RSSI fix is 1.5–2 m
    /// off, and with radios awake a visible tagged person's binding wavers (docs/multi-target.md).
    #[serde(default)]
    pub unseen_tags: bool,
    /// Height above the floor of the point a track's position stands for, metres (a robot's
    /// centre, a person's mid-height): where a lone camera's ray is cut to start a track and
    /// where ML fusion lifts detections. Absent: 0.5, or in the simulation half the height of
    /// its first target.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub target_plane_z: Option<f64>,
    /// RGB colours the reference-colour segmentation looks for (paper 000 §6.1.1 assumes the
    /// target's colour is known). Empty: in the simulation, its targets' colours.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub target_colours: Vec<[u8; 3]>,
    /// What cameras make of their frames: segmented regions (the default) or paper 004's
    /// per-person particle filters.
    #[serde(default)]
    pub camera_tracker: CameraTracker,
    /// The particle filter tracker's parameters (paper 004's values by default).
    #[serde(default)]
    pub particle: ParticleParams,
    /// The grid estimator's parameters (`fusion = "grid"`).
    #[serde(default)]
    pub grid: GridMethod,
}

pub use acoustic_spec::{AcousticSpec, GridMethod, low_band};

impl Method {
    /// How far from a node's time a capture may be stamped and still be fused, ms: two filter
    /// steps, at least 500 ms. Frames and packets are fused at their capture time, so one
    /// stamped further off (a clock that is off, a stale buffer) is refused rather than carried
    /// along the track. Cameras and heads share this bound.
    pub fn capture_max_age_ms(&self) -> u64 {
        (2 * self.step_ms).max(500)
    }

    /// [`Method::target_plane_z`] or its default, metres.
    pub fn target_plane_z(&self) -> f64 {
        self.target_plane_z.unwrap_or(0.5)
    }
}

impl Default for Method {
    fn default() -> Self {
        Method {
            fusion: Fusion::DistributedEif,
            activation: Activation::ThreeMode,
            segmentation: Segmentation::AdaptiveBackground,
            step_ms: 200,
            deadline_ms: 80,
            pixel_sigma: 18.0,
            motion: MotionModel::default(),
            rssi_default: RssiModel::default(),
            rssi_survey: false,
            rssi_window: 20,
            rssi_epsilon: 1e-3,
            energy_weight: 1e-3,
            previous_point: false,
            track_timeout_ms: 3000,
            gate_chi2: 13.8,
            drop_lost_cameras: false,
            unseen_tags: false,
            target_plane_z: None,
            target_colours: Vec::new(),
            camera_tracker: CameraTracker::Segmentation,
            particle: ParticleParams::default(),
            grid: GridMethod::default(),
        }
    }
}

/// Power figures (paper 002: CMUcam3 650 mW; TelosB 69 mW active, 7.2 mW low-power).
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, rename_all = "kebab-case")]
pub struct PowerFigures {
    pub camera_mw: f64,
    pub node_active_mw: f64,
    pub node_low_power_mw: f64,
}

impl Default for PowerFigures {
    fn default() -> Self {
        PowerFigures {
            camera_mw: 650.0,
            node_active_mw: 69.0,
            node_low_power_mw: 7.2,
        }
    }
}

impl PowerFigures {
    /// Power drawn in a mode, mW.
    pub fn in_mode(&self, mode: crate::Mode) -> f64 {
        match mode {
            crate::Mode::Active => self.camera_mw + self.node_active_mw,
            crate::Mode::CameraOff => self.node_active_mw,
            crate::Mode::Inactive => self.node_low_power_mw,
        }
    }
}

/// What a node does.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum NodeRole {
    Camera,
    Head,
    Server,
    /// A two-microphone acoustic node (paper 001): ILD vectors to its head.
    Acoustic,
}

/// One node of the deployment.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, rename_all = "kebab-case")]
pub struct NodeSpec {
    pub id: u32,
    pub role: NodeRole,
    /// Host the node runs on (for `ocelli deploy`).
    #[serde(default = "default_host")]
    pub host: String,
    /// TCP address this node listens on (heads and the server) — `host:port`.
    #[serde(default)]
    pub listen: Option<String>,
    /// The head a camera reports to.
    #[serde(default)]
    pub head: Option<u32>,
    /// Camera geometry (cameras only).
    #[serde(default)]
    pub camera: Option<CameraSpec>,
    /// Per-node power figures overriding the scenario's (a low battery, another board).
    #[serde(default)]
    pub power: Option<PowerFigures>,
    /// Extra activation cost multiplier (a low battery makes a node more expensive).
    #[serde(default = "one")]
    pub cost_factor: f64,
    /// Area a head covers, `[xmin, ymin, xmax, ymax]` (heads only).
    #[serde(default)]
    pub region: Option<[f64; 4]>,
    /// Whether this node measures RSSI of the target's tag.
    #[serde(default = "yes")]
    pub rssi: bool,
    /// Microphones, analysis and fingerprints (acoustic nodes only).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub acoustic: Option<AcousticSpec>,
    /// Where the node's radio sits, `[x, y, z]` metres (camera nodes; default: the camera's
    /// centre). A camera node without `camera` geometry is a radio-only node and needs it.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub position: Option<[f64; 3]>,
    /// Where a real node's radio readings come from (camera nodes): `ble`, `ble:ADAPTER` or
    /// `file:PATH.mbd@SENSOR-MAC` (relative to the scenario file). Absent: launched nodes hear
    /// the simulated world, others no radio unless `ocelli camera --radio` names one.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub radio: Option<RadioSpec>,
}

impl NodeSpec {
    /// A camera node without a camera: it only hears radio tags (CameraOff is its working
    /// mode; it is never Active).
    pub fn radio_only(&self) -> bool {
        self.role == NodeRole::Camera && self.camera.is_none()
    }
}

fn default_host() -> String {
    "localhost".into()
}
fn one() -> f64 {
    1.0
}
fn yes() -> bool {
    true
}

/// Camera geometry: inline, or OpenCV calibration files.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, rename_all = "kebab-case")]
pub struct CameraSpec {
    #[serde(default)]
    pub intrinsics: Option<Intrinsics>,
    #[serde(default)]
    pub distortion: Distortion,
    #[serde(default)]
    pub pose: Option<PoseSpec>,
    /// OpenCV `FileStorage` intrinsic file (camera matrix + distortion); relative to the
    /// scenario file.
    #[serde(default)]
    pub opencv_intrinsic: Option<PathBuf>,
    /// OpenCV `FileStorage` extrinsic file (rvec, tvec).
    #[serde(default)]
    pub opencv_extrinsic: Option<PathBuf>,
    /// Frames per second the camera captures.
    #[serde(default = "default_fps")]
    pub fps: f64,
}

fn default_fps() -> f64 {
    5.0
}

/// A camera pose: placed and aimed, or OpenCV `rvec`/`tvec` (world → camera).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
// `rename_all_fields`, not `rename_all`: an untagged enum's keys are its variants' fields.
#[serde(
    deny_unknown_fields,
    rename_all_fields = "kebab-case",
    untagged,
    expecting = "a pose: `{ position = [x, y, z], look-at = [x, y, z] }` or `{ rvec = [..], tvec = [..] }`"
)]
pub enum PoseSpec {
    LookAt { position: [f64; 3], look_at: [f64; 3] },
    Rodrigues { rvec: [f64; 3], tvec: [f64; 3] },
}

impl PoseSpec {
    pub fn to_pose(&self) -> Option<Pose> {
        match *self {
            PoseSpec::LookAt { position, look_at } => {
                Pose::look_at(Vector3::from(position), Vector3::from(look_at), Vector3::z())
            }
            PoseSpec::Rodrigues { rvec, tvec } => Some(Pose::from_rvec_tvec(rvec, tvec)),
        }
    }
}

/// A scenario that could not be loaded.
#[derive(Debug, Error)]
pub enum ScenarioError {
    #[error("cannot read scenario {path}: {source}")]
    Io { path: PathBuf, source: std::io::Error },
    #[error("scenario {path}: {message}")]
    Parse { path: String, message: String },
    #[error("scenario {path}: {field}: {problem}")]
    Invalid {
        path: String,
        field: String,
        problem: String,
    },
}

impl Scenario {
    /// The embedded default scenario.
    pub fn default_scenario() -> Scenario {
        Scenario::from_toml(DEFAULT_SCENARIO_TOML, "<default>")
            .expect("the embedded default scenario is valid")
    }

    /// Parse and validate TOML text; `origin` names it in errors.
    ///
    /// # Errors
    /// A parse error with the TOML path and what was expected, or the first semantic problem.
    pub fn from_toml(text: &str, origin: &str) -> Result<Scenario, ScenarioError> {
        let scenario: Scenario = toml::from_str(text).map_err(|e| ScenarioError::Parse {
            path: origin.into(),
            message: e.to_string(),
        })?;
        scenario.validate(origin, None)?;
        Ok(scenario)
    }

    /// Load a scenario file; OpenCV calibration paths are resolved relative to it.
    ///
    /// # Errors
    /// As [`Scenario::from_toml`], plus IO errors naming the path.
    pub fn load(path: &Path) -> Result<Scenario, ScenarioError> {
        let text = std::fs::read_to_string(path).map_err(|source| ScenarioError::Io {
            path: path.into(),
            source,
        })?;
        let origin = path.display().to_string();
        let mut scenario: Scenario = toml::from_str(&text).map_err(|e| ScenarioError::Parse {
            path: origin.clone(),
            message: e.to_string(),
        })?;
        let base = path.parent().unwrap_or(Path::new("."));
        for node in &mut scenario.nodes {
            node.radio = node.radio.take().map(|r| r.resolved(base));
            if let Some(path) = node.acoustic.as_mut().and_then(|a| a.fingerprints.as_mut())
                && path.is_relative()
            {
                *path = base.join(&*path);
            }
            if let Some(cam) = &mut node.camera {
                for p in [&mut cam.opencv_intrinsic, &mut cam.opencv_extrinsic]
                    .into_iter()
                    .flatten()
                {
                    if p.is_relative() {
                        *p = base.join(&*p);
                    }
                }
            }
        }
        scenario.validate(&origin, None)?;
        Ok(scenario)
    }

    pub fn to_toml(&self) -> String {
        toml::to_string_pretty(self).expect("scenarios always serialize")
    }

    pub fn node(&self, id: u32) -> Option<&NodeSpec> {
        self.nodes.iter().find(|n| n.id == id)
    }

    pub fn cameras(&self) -> impl Iterator<Item = &NodeSpec> {
        self.nodes.iter().filter(|n| n.role == NodeRole::Camera)
    }

    pub fn heads(&self) -> impl Iterator<Item = &NodeSpec> {
        self.nodes.iter().filter(|n| n.role == NodeRole::Head)
    }

    /// The acoustic nodes.
    pub fn acoustic_nodes(&self) -> impl Iterator<Item = &NodeSpec> {
        self.nodes.iter().filter(|n| n.role == NodeRole::Acoustic)
    }

    /// The head a camera or acoustic node reports to: its own, else the first head.
    pub fn head_of(&self, id: u32) -> Option<u32> {
        self.node(id)
            .and_then(|n| n.head)
            .or_else(|| self.heads().next().map(|h| h.id))
    }

    pub fn server(&self) -> Option<&NodeSpec> {
        self.nodes.iter().find(|n| n.role == NodeRole::Server)
    }

    /// Power figures of a node (its override or the scenario's).
    pub fn power_of(&self, id: u32) -> PowerFigures {
        self.node(id).and_then(|n| n.power).unwrap_or(self.power)
    }

    /// Build the camera model of a camera node (reads OpenCV files if it names them).
    ///
    /// # Errors
    /// Missing geometry or an unreadable calibration file, naming the node.
    pub fn camera_model(&self, id: u32) -> Result<CameraModel, ScenarioError> {
        let bad = |field: &str, problem: String| ScenarioError::Invalid {
            path: self.name.clone(),
            field: format!("nodes[id={id}].{field}"),
            problem,
        };
        let node = self.node(id).ok_or_else(|| bad("id", "no such node".into()))?;
        let cam = node
            .camera
            .as_ref()
            .ok_or_else(|| bad("camera", "not a camera node".into()))?;
        let (mut intrinsics, mut distortion) = (cam.intrinsics, cam.distortion);
        if let Some(path) = &cam.opencv_intrinsic {
            // OpenCV files rarely carry the image size; inline intrinsics may supply it.
            let size = intrinsics.map(|k| (k.width, k.height));
            let (k, d) = crate::opencv::read_intrinsics_with(path, size)
                .map_err(|e| bad("camera.opencv-intrinsic", e.to_string()))?;
            intrinsics = Some(k);
            distortion = d;
        }
        let pose = match (&cam.opencv_extrinsic, &cam.pose) {
            (Some(path), _) => crate::opencv::read_extrinsics(path)
                .map_err(|e| bad("camera.opencv-extrinsic", e.to_string()))?,
            (None, Some(p)) => p
                .to_pose()
                .ok_or_else(|| bad("camera.pose", "degenerate pose".into()))?,
            (None, None) => return Err(bad("camera", "no pose".into())),
        };
        let intrinsics = intrinsics.ok_or_else(|| bad("camera.intrinsics", "missing".into()))?;
        Ok(CameraModel {
            intrinsics,
            distortion,
            pose,
        })
    }

    /// Where node `id`'s radio sits: its `position`, else its camera's centre.
    ///
    /// # Errors
    /// The node does not exist, or has neither a position nor usable camera geometry.
    pub fn sensor_position(&self, id: u32) -> Result<Vector3<f64>, ScenarioError> {
        match self.node(id).and_then(|n| n.position) {
            Some(p) => Ok(Vector3::from(p)),
            None => Ok(self.camera_model(id)?.pose.centre()),
        }
    }

    /// Camera → head map from the scenario (cameras with no head go to the first head).
    pub fn clusters(&self) -> BTreeMap<NodeId, Vec<NodeId>> {
        let first = self.heads().next().map(|h| h.id);
        let mut out: BTreeMap<NodeId, Vec<NodeId>> =
            self.heads().map(|h| (NodeId(h.id), Vec::new())).collect();
        for c in self.cameras() {
            if let Some(h) = c.head.or(first) {
                out.entry(NodeId(h)).or_default().push(NodeId(c.id));
            }
        }
        out
    }
}
