//! What a head needs to know, built from the scenario: its id, the server, the method, a
//! table of every camera node it may be given (camera model, position, power figures, cost
//! factor), with the ones the scenario assigns to it marked as members, and its acoustic nodes
//! with their fingerprints (read here, checked against the room).

use crate::fusion::ml::DepthHandling;
use nalgebra::Vector3;
use proto::NodeId;
use proto::acoustic::{AcousticError, FingerprintDb};
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
    #[error("acoustic node {node}: {source}")]
    Fingerprints { node: u32, source: AcousticError },
    #[error(
        "acoustic node {node}: fingerprint file {path} was analysed with {found}, the node with {expected}"
    )]
    IldSettings {
        node: u32,
        path: String,
        found: String,
        expected: String,
    },
    #[error("grid fusion: {0}")]
    Grid(#[from] crate::grid::GridError),
}

/// One acoustic node as the head sees it.
#[derive(Clone, Debug, PartialEq)]
pub struct AcousticInfo {
    pub id: NodeId,
    /// In this head's cluster.
    pub member: bool,
    /// The fingerprints its ILD vectors are compared with (`None`: the scenario names no file;
    /// its observations are counted and not fused).
    pub fingerprints: Option<FingerprintDb>,
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
    /// The floor this head covers, `[xmin, ymin, xmax, ymax]` (the scenario's `region`): it
    /// starts no track on a live head's region farther than [`BIRTH_REGION_MARGIN_M`] from its
    /// own. `None`: anywhere in the world.
    pub region: Option<[f64; 4]>,
    /// The other heads and their regions: floor no live head's region covers is anybody's.
    pub other_regions: Vec<(NodeId, [f64; 4])>,
    /// Height assumed for single-camera priors and for ML's known plane, metres.
    pub target_plane_z: f64,
    /// How ML gets depth.
    pub ml_depth: DepthHandling,
    /// Acoustic nodes (paper 001), members or not.
    pub acoustic: Vec<AcousticInfo>,
}

/// How far outside its region a head still starts tracks, metres (distance to the region): a
/// person crossing the border is started by either head, and the server joins the two.
///
/// Cameras see far beyond the region they are aimed at, and a head once started a track
/// wherever its cameras agreed. In a hall tiled by five heads that made a track of one walking
/// person in every neighbouring cluster too, triangulated by that cluster's distant cameras
/// (floor σ often 0.8–3 m, 1–3.4 m off) — duplicates the server took for new people. Measured
/// (`proto/scenarios/hall.toml`, measurement level, seeds 1–16): MOTA 0.527 → 0.562, global
/// ids 34.1 → 30.6, false tracks 12.3 → 10.0, IDF1 0.479 → 0.487; the two-head crowd room
/// (seeds 7–16), where every camera sees the whole floor, unchanged (0.740 → 0.744).
pub const BIRTH_REGION_MARGIN_M: f64 = 1.0;

// Floor a live head's region covers, grown by the births' slack around the world's box, must
// be within a neighbour's margin too, or a birth just past a shared wall would be nobody's.
const _: () = assert!(crate::association::BIRTH_BOUNDS_MARGIN <= BIRTH_REGION_MARGIN_M);

/// Member cameras from which a cluster asks three cameras to agree on a birth, not two.
pub const CROWDED_CLUSTER_CAMERAS: usize = 6;

/// Fewest cameras that must agree to start a track: 1 in a cluster of one node, 3 in a cluster
/// of [`CROWDED_CLUSTER_CAMERAS`] member cameras or more, else 2 (also for a single camera among
/// radio-only nodes, which therefore starts no camera track). With many people in view, two
/// cameras' free detections of *different* people meet on a floor point where nobody is, and a
/// third camera rarely sees anyone there. Measured (`experiment crowd`, 5 runs, pixel level):
/// distributed MOTA 0.385 → 0.416, IDF1 0.329 → 0.343, global ids 38.6 → 27.0; centralized
/// 0.328 → 0.412, 0.321 → 0.340, 55.6 → 40.2; the robot unchanged (0.109 → 0.111 m). A small
/// cluster (paper 000's EIF3 and EIF5 runs) keeps two: three of its few cameras may never see
/// a target at once.
pub fn birth_min_cameras(members: usize, member_cameras: usize) -> usize {
    match (members, member_cameras) {
        (0..=1, _) => 1,
        (_, c) if c >= CROWDED_CLUSTER_CAMERAS => 3,
        _ => 2,
    }
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
        let acoustic = acoustic_nodes(scenario, id)?;
        if scenario.method.fusion == proto::scenario::Fusion::Grid {
            // Build the grid once here so that a head never starts with one it cannot build.
            crate::grid::Grid::new(&scenario.world, scenario.method.grid.cell_m)?;
        }
        let target_plane_z = scenario.method.target_plane_z();
        let member_count = nodes.iter().filter(|n| n.member).count();
        let member_cameras = nodes.iter().filter(|n| n.member && !n.radio_only).count();
        Ok(HeadConfig {
            id: NodeId(id),
            server: scenario.server().map(|s| NodeId(s.id)),
            method: scenario.method.clone(),
            nodes,
            bounds: (scenario.world.min, scenario.world.max),
            walls: scenario.world.walls.clone(),
            birth_min_cameras: birth_min_cameras(member_count, member_cameras),
            region: scenario.node(id).and_then(|n| n.region),
            other_regions: scenario
                .heads()
                .filter(|h| h.id != id)
                .filter_map(|h| h.region.map(|r| (NodeId(h.id), r)))
                .collect(),
            target_plane_z,
            ml_depth: DepthHandling::KnownPlane {
                z: target_plane_z,
                sigma: 0.05,
            },
            acoustic,
        })
    }

    /// The world's box and walls, as the grid estimator builds its cells on them.
    pub fn world(&self) -> proto::scenario::World {
        proto::scenario::World {
            min: self.bounds.0,
            max: self.bounds.1,
            walls: self.walls.clone(),
            radio: proto::scenario::RadioWorld::default(),
            geo: None,
        }
    }
}

/// Every acoustic node of `scenario`, those reporting to head `id` marked, each with its
/// fingerprints if the scenario names a file.
///
/// # Errors
/// A fingerprint file that cannot be read, is of another format or version, was surveyed in
/// another room, or was analysed with other ILD settings than the node's.
fn acoustic_nodes(scenario: &Scenario, id: u32) -> Result<Vec<AcousticInfo>, ConfigError> {
    let mut out = Vec::new();
    for n in scenario.acoustic_nodes() {
        let member = scenario.head_of(n.id) == Some(id);
        let spec = n.acoustic.as_ref();
        let fingerprints = match spec.and_then(|a| a.fingerprints.as_ref()) {
            None => None,
            Some(path) => {
                let fail = |source| ConfigError::Fingerprints { node: n.id, source };
                let db = FingerprintDb::load(path).map_err(fail)?;
                db.check_room(&scenario.world, &path.display().to_string())
                    .map_err(fail)?;
                if let Some(a) = spec
                    && db.settings() != &a.ild
                {
                    return Err(ConfigError::IldSettings {
                        node: n.id,
                        path: path.display().to_string(),
                        found: format!("{:?}", db.settings()),
                        expected: format!("{:?}", a.ild),
                    });
                }
                Some(db)
            }
        };
        out.push(AcousticInfo {
            id: NodeId(n.id),
            member,
            fingerprints,
        });
    }
    Ok(out)
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
        // Ten and eleven cameras per head: a crowded cluster's births need three.
        assert!(members.len() >= CROWDED_CLUSTER_CAMERAS);
        assert_eq!(c.birth_min_cameras, 3);
    }

    #[test]
    fn births_need_one_camera_alone_two_in_a_small_cluster_three_in_a_large_one() {
        assert_eq!(birth_min_cameras(1, 1), 1);
        assert_eq!(birth_min_cameras(3, 3), 2);
        assert_eq!(birth_min_cameras(6, 5), 2, "radio-only members are no cameras");
        assert_eq!(birth_min_cameras(6, 6), 3);
        assert_eq!(birth_min_cameras(21, 21), 3);
    }
}
